"""Clip labels (file name vs JSON vs cfg), filters, loading and the preprocessing cache."""

from __future__ import annotations

import json
from collections import Counter

import numpy as np
import pytest

import emotive.io.bvh
from emotive.data import clips as clips_mod
from emotive.data.clips import list_clips, load_clips, read_clip_index, select_clips
from emotive.data.emotion import ALL_LABELS
from emotive.data.registry import get_dataset
from emotive.errors import DataError
from emotive.io.bvh import read_bvh


class TestLabelsSynthetic:
    def test_index(self, fake):
        clips = read_clip_index(fake.folder, "fake-1")
        assert len(clips) == 18
        walk = next(c for c in clips if c.name == "dataset-1_walk-left_sad_002")
        assert (walk.dataset, walk.content, walk.style, walk.take) == (
            "fake-1", "walk-left", "sad", 2
        )
        assert walk.path == fake.folder / "data" / "dataset-1_walk-left_sad_002.bvh"
        assert [c.name for c in clips] == sorted(c.name for c in clips)
        assert {c.emotion for c in clips} == {"neutral", "happy", "sad"}

    def test_json_disagreeing_with_name(self, fake):
        label = fake.folder / "data" / "dataset-1_bow_happy_001.json"
        label.write_text('{"content": 2, "style": 2}')
        with pytest.raises(DataError, match=r"happy_001\.json says .*'sad'.*disagree"):
            read_clip_index(fake.folder, "fake-1")

    def test_missing_json(self, fake):
        (fake.folder / "data" / "dataset-1_bow_happy_001.json").unlink()
        with pytest.raises(DataError, match=r"dataset-1_bow_happy_001\.json is missing"):
            read_clip_index(fake.folder, "fake-1")

    @pytest.mark.parametrize("text", ['{"content": 0}', "not json", '{"content": "a", "style": 1}'])
    def test_malformed_json(self, fake, text):
        (fake.folder / "data" / "dataset-1_bow_happy_001.json").write_text(text)
        with pytest.raises(DataError, match="must hold"):
            read_clip_index(fake.folder, "fake-1")

    def test_ids_out_of_range(self, fake):
        label = fake.folder / "data" / "dataset-1_bow_happy_001.json"
        label.write_text('{"content": 9, "style": 0}')
        with pytest.raises(DataError, match="out of range"):
            read_clip_index(fake.folder, "fake-1")

    def test_bad_file_name(self, fake):
        (fake.folder / "data" / "walk.bvh").write_text("x")
        with pytest.raises(DataError, match=r"walk\.bvh: expected a name dataset-1_"):
            read_clip_index(fake.folder, "fake-1")

    def test_unknown_style_in_name(self, fake):
        (fake.folder / "data" / "dataset-1_walk_proud_001.bvh").write_text("x")
        with pytest.raises(DataError, match="'proud' is not in"):
            read_clip_index(fake.folder, "fake-1")

    def test_cfg_differs_from_registry(self, fake):
        (fake.folder / "cfg" / "style_label.txt").write_text("dataset-1_normal\ndataset-1_sad")
        with pytest.raises(DataError, match="differ from the registry"):
            read_clip_index(fake.folder, "fake-1")

    def test_filters(self, fake):
        clips = read_clip_index(fake.folder, "fake-1")
        assert {c.content for c in select_clips(clips, locomotion=True)} == {"walk", "walk-left"}
        picked = select_clips(clips, contents=["bow"], styles=["sad"])
        assert [c.name for c in picked] == ["dataset-1_bow_sad_001", "dataset-1_bow_sad_002"]
        with pytest.raises(DataError, match=r"unknown styles \['angry'\]"):
            select_clips(clips, styles=["angry"])


class TestLoadSynthetic:
    def test_load_matches_reader_and_labels(self, fake):
        from emotive.data.store import fetch

        fetch("fake-1", fake.archive)
        loaded = load_clips("fake-1")
        assert [c.motion.num_frames for c in loaded] == [fake.frames[c.info.name] for c in loaded]
        first = loaded[0]
        direct = read_bvh(first.info.path)
        np.testing.assert_array_equal(first.motion.rotations, direct.rotations)
        np.testing.assert_array_equal(first.motion.positions, direct.positions)
        assert first.motion.skeleton.same_as(direct.skeleton) and first.motion.fps == 30.0
        meta = first.motion.metadata
        assert (meta["content"], meta["style"], meta["emotion"], meta["take"]) == (
            "bow", "happy", "happy", 1
        )
        assert [c.info.style for c in load_clips("fake-1", styles=["normal"])] == ["normal"] * 6

    def test_first_load_shows_progress_only_when_asked(self, fake, monkeypatch, capfd):
        from emotive.data.store import fetch

        fetch("fake-1", fake.archive)
        monkeypatch.setenv("FORCE_COLOR", "1")  # rich draws bars only on a terminal
        load_clips("fake-1")
        assert "parsing fake-1" not in capfd.readouterr().err
        clips_mod.preprocessed_path("fake-1").unlink()
        load_clips("fake-1", progress=True)
        assert "parsing fake-1" in capfd.readouterr().err
        load_clips("fake-1", progress=True)  # cached: nothing to parse, no bar
        assert "parsing fake-1" not in capfd.readouterr().err

    def test_second_load_reads_the_cache(self, fake, monkeypatch, isolated_home):
        from emotive.data.store import fetch

        fetch("fake-1", fake.archive)
        first = load_clips("fake-1")
        files = list((isolated_home / "preprocessed").glob("fake-1-*.npz"))
        assert len(files) == 1

        def no_parsing(*args, **kwargs):
            raise AssertionError("the second load parsed a BVH file")

        monkeypatch.setattr(emotive.io.bvh, "read_bvh", no_parsing)
        second = load_clips("fake-1")
        for a, b in zip(first, second, strict=True):
            np.testing.assert_array_equal(a.motion.rotations, b.motion.rotations)

    def test_code_change_makes_a_new_cache_file(self, fake, monkeypatch, isolated_home):
        from emotive.data.store import fetch

        fetch("fake-1", fake.archive)
        load_clips("fake-1")
        old = clips_mod.preprocessed_path("fake-1")
        monkeypatch.setattr(clips_mod, "code_fingerprint", lambda: "another version")
        new = clips_mod.preprocessed_path("fake-1")
        assert new != old
        load_clips("fake-1")
        assert list((isolated_home / "preprocessed").glob("fake-1-*.npz")) == [new]

    def test_cache_key_depends_on_options_and_archive(self, fake, monkeypatch):
        key = clips_mod.cache_key("fake-1")
        assert clips_mod.cache_key("fake-1", unit="cm") != key
        other = get_dataset("fake-1").__class__(**{**vars(fake.info), "sha256": "0" * 64})
        assert clips_mod.cache_key(other) != key


class TestRealData:
    @pytest.mark.parametrize(
        ("name", "count", "contents", "styles"),
        [("bandai-namco-1", 174, 16, 15), ("bandai-namco-2-locomotion", 962, 4, 7)],
    )
    def test_every_file_labelled(self, home, name, count, contents, styles):
        info = get_dataset(name)
        clips = list_clips(name)
        folder = home / "datasets" / info.folder / "data"
        assert len(clips) == count == info.clips
        assert len(list(folder.glob("*.bvh"))) == count
        for clip in clips:
            label = json.loads(clip.path.with_suffix(".json").read_text())
            assert info.contents[label["content"]] == clip.content
            assert info.styles[label["style"]] == clip.style
            assert clip.emotion in ALL_LABELS
        assert len({c.content for c in clips}) == contents
        assert len({c.style for c in clips}) == styles

    def test_cfg_files_match_registry(self, home):
        for name in ("bandai-namco-1", "bandai-namco-2-locomotion"):
            info = get_dataset(name)
            cfg = home / "datasets" / info.folder / "cfg"
            prefix = "dataset-1_" if name.endswith("1") else "dataset-2_"

            def labels(file: str, prefix: str = prefix, cfg=cfg) -> list[str]:
                return [x.removeprefix(prefix) for x in (cfg / file).read_text().split()]

            assert labels("style_label.txt") == list(info.styles)
            assert labels("content_label.txt") == list(info.contents)

    def test_locomotion_filter_dataset1(self, home):
        clips = list_clips("bandai-namco-1", locomotion=True)
        assert Counter(c.content for c in clips) == {
            "walk": 30, "walk-back": 15, "walk-left": 15, "walk-right": 15, "run": 15, "dash": 15
        }

    def test_load_dataset1_twice(self, home, monkeypatch):
        first = load_clips("bandai-namco-1")
        monkeypatch.setattr(emotive.io.bvh, "read_bvh", lambda *a, **k: pytest.fail("parsed"))
        second = load_clips("bandai-namco-1")
        assert len(first) == len(second) == 174
        assert sum(c.motion.num_frames for c in second) == 31914
        assert {c.motion.fps for c in second} == {30.0}
        np.testing.assert_array_equal(first[7].motion.rotations, second[7].motion.rotations)
        direct = read_bvh(home / "datasets" / get_dataset("bandai-namco-1").folder / "data"
                          / f"{second[7].info.name}.bvh")
        np.testing.assert_array_equal(second[7].motion.positions, direct.positions)
