"""Windows: cutting, provenance, emotions, resampling and mirroring through emotive.core.ops."""

from __future__ import annotations

import sys
import types
from pathlib import Path

import numpy as np
import pytest

from emotive.data.clips import Clip, ClipInfo, load_clips
from emotive.data.emotion import DEFAULT_LABELS
from emotive.data.splits import split_clips
from emotive.data.store import fetch
from emotive.data.windows import make_windows, mirror_content, window_starts
from emotive.errors import DataError, EmotionError


def clip(motion, name: str, content: str = "walk", style: str = "happy") -> Clip:
    info = ClipInfo("fake-1", name, Path(f"{name}.bvh"), content, style, 1)
    return Clip(info, motion)


def test_window_starts():
    np.testing.assert_array_equal(window_starts(10, 4, 3), [0, 3, 6])
    np.testing.assert_array_equal(window_starts(10, 10, 1), [0])
    assert window_starts(3, 4, 1).size == 0
    with pytest.raises(DataError, match=">= 1"):
        window_starts(10, 0, 1)


def test_cut_and_provenance(random_motion):
    a, b = random_motion(frames=25, seed=1), random_motion(frames=7, seed=2)
    c = random_motion(frames=12, seed=3)
    clips = [clip(a, "a"), clip(b, "b", style="sad"), clip(c, "c", content="run", style="normal")]
    w = make_windows(clips, length=8, stride=4)
    assert len(w) == 5 + 0 + 2
    assert w.rotations.shape == (7, 8, 5, 4) and w.positions.shape == (7, 8, 5, 3)
    assert w.rotations.dtype == np.float32 and w.fps == 30.0
    np.testing.assert_array_equal(w.clip_index, [0, 0, 0, 0, 0, 2, 2])
    np.testing.assert_array_equal(w.start, [0, 4, 8, 12, 16, 0, 4])
    np.testing.assert_allclose(w.rotations[3], a.rotations[12:20], rtol=1e-6)
    np.testing.assert_allclose(w.positions[6], c.positions[4:12], rtol=1e-6)
    assert not w.mirrored.any()
    assert w.styles == ["happy"] * 5 + ["normal"] * 2
    emotions = w.emotions()
    assert emotions.shape == (7, 4)
    np.testing.assert_array_equal(emotions[-1], np.eye(4)[DEFAULT_LABELS.index("neutral")])
    with pytest.raises(EmotionError, match="not one of this model's labels"):
        make_windows([clip(a, "a", style="proud")], 8, 4).emotions()


def test_mixed_rates_need_fps(random_motion):
    a = random_motion(frames=20)
    b = a.replace(fps=60.0)
    with pytest.raises(DataError, match="different frame rates"):
        make_windows([clip(a, "a"), clip(b, "b")], 4, 4)


def test_resample_and_mirror_go_through_ops(random_motion, monkeypatch):
    calls = []

    def resample(motion, fps):
        calls.append(("resample", fps))
        return motion.replace(rotations=motion.rotations[::2], positions=motion.positions[::2],
                              fps=fps)

    def mirror(motion):
        calls.append(("mirror", None))
        return motion.replace(positions=motion.positions * np.array([-1.0, 1.0, 1.0]))

    fake_ops = types.ModuleType("emotive.core.ops")
    fake_ops.resample, fake_ops.mirror = resample, mirror
    monkeypatch.setitem(sys.modules, "emotive.core.ops", fake_ops)
    a = random_motion(frames=20)
    w = make_windows([clip(a, "a", content="walk-left")], length=5, stride=5, fps=15, mirror=True)
    assert calls == [("resample", 15.0), ("mirror", None)]
    assert w.fps == 15.0 and len(w) == 4
    np.testing.assert_array_equal(w.mirrored, [False, False, True, True])
    assert w.contents == ["walk-left", "walk-left", "walk-right", "walk-right"]
    np.testing.assert_allclose(w.positions[2, :, :, 0], -w.positions[0, :, :, 0], rtol=1e-6)


def test_with_the_real_ops(fake):
    pytest.importorskip("emotive.core.ops", reason="emotive.core.ops is not written yet")
    fetch("fake-1", fake.archive)
    loaded = load_clips("fake-1", contents=["walk-left"], styles=["sad"])
    frames = [c.motion.num_frames for c in loaded]
    w = make_windows(loaded, length=10, stride=5, fps=15, mirror=True)
    per_clip = [len(window_starts(round(n / 2), 10, 5)) for n in frames]
    assert w.fps == 15.0 and len(w) == 2 * sum(per_clip)
    first = slice(0, per_clip[0])
    mirrored = slice(per_clip[0], 2 * per_clip[0])
    assert not w.mirrored[first].any() and w.mirrored[mirrored].all()
    # The root's world X is reflected.
    np.testing.assert_allclose(
        w.positions[mirrored, :, 0, 0], -w.positions[first, :, 0, 0], atol=1e-6
    )


def test_mirror_content():
    assert mirror_content("walk-left") == "walk-right"
    assert mirror_content("raise-up-right-hand") == "raise-up-left-hand"
    assert mirror_content("walk") == "walk"


def test_real_windows_stay_in_their_split(home):
    styles = ["normal", "happy", "sad", "angry"]
    clips = load_clips("bandai-namco-1", locomotion=True, styles=styles)
    parts = split_clips([c.info for c in clips])
    by_name = {c.info.name: c for c in clips}
    windows = {s: make_windows([by_name[i.name] for i in parts[s]], 60, 30) for s in parts}
    names = {s: {w.clips[i].name for i in w.clip_index} for s, w in windows.items()}
    assert not (names["train"] & names["val"]) and not (names["train"] & names["test"])
    for w in windows.values():
        assert w.rotations.shape[1:] == (60, 22, 4) == (60, w.skeleton.num_joints, 4)
        assert set(np.argmax(w.emotions(), 1)) == {0, 1, 2, 3}
