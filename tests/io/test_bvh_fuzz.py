"""The BVH reader under hostile input: every mutant of the fuzz corpus is a BVHError or a
plausible motion, fast and small; a pipe is refused at once; the CLI prints one line."""

from __future__ import annotations

import os
import threading
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from bvh_mutants import N_FRAMES, base_motion, base_text, deep_chain, mutants

from cli_helpers import run_main
from emotive.errors import BVHError
from emotive.io import bvh_limits as limits
from emotive.io import input_limits
from emotive.io.bvh import read_bvh, write_bvh

#: Per-mutant budgets: far above what a mutant takes (under 0.3 s, under 12 MB traced). The
#: time is the process's CPU time, which other jobs on a busy machine do not stretch.
SECONDS_PER_MUTANT = 2.0
PEAK_BYTES_PER_MUTANT = 200 * 2**20
#: Longest message of a refused mutant: the longest fixed text plus quotes of at most 80
#: characters (a ``Frames:`` of 5,000 digits was once echoed whole).
MAX_PROBLEM_CHARS = 300


def assert_plausible(motion) -> None:
    """A motion within every limit of :mod:`emotive.io.bvh_limits`."""
    sk = motion.skeleton
    assert limits.MIN_FPS <= motion.fps <= limits.MAX_FPS
    assert sk.num_joints <= limits.MAX_JOINTS and motion.num_frames <= limits.MAX_FRAMES
    for arr in (motion.rotations, motion.positions, sk.offsets, sk.end_site_offsets):
        assert np.isfinite(arr).all()
    for arr in (motion.positions, sk.offsets, sk.end_site_offsets):
        assert np.abs(arr).max(initial=0.0) <= limits.MAX_LENGTH_M
    np.testing.assert_allclose(np.linalg.norm(motion.rotations, axis=-1), 1.0, atol=1e-9)
    assert motion.metadata["file_unit"] in limits.UNITS


def test_corpus_is_large_and_deterministic():
    corpus = mutants()
    assert len(corpus) >= 2000
    assert len({name for name, _ in corpus}) == len(corpus)
    assert corpus[:50] == mutants()[:50]


def test_every_mutant_is_a_bvh_error_or_a_plausible_motion(tmp_path):
    outcomes: dict[str, int] = {"error": 0, "read": 0}
    slow, big, crashes = [], [], []
    tracemalloc.start()
    try:
        for name, data in mutants():
            path = tmp_path / f"{name}.bvh"
            path.write_bytes(data)
            tracemalloc.reset_peak()
            start = time.process_time()
            try:
                motion = read_bvh(path)
            except BVHError as exc:
                assert "\n" not in str(exc) and str(path) in str(exc), (name, str(exc))
                assert len(exc.problem) <= MAX_PROBLEM_CHARS, (name, str(exc)[:400])
                outcomes["error"] += 1
            except Exception as exc:
                crashes.append(f"{name}: {type(exc).__name__}: {exc}"[:300])
            else:
                assert_plausible(motion)
                outcomes["read"] += 1
            seconds = time.process_time() - start
            peak = tracemalloc.get_traced_memory()[1]
            if seconds > SECONDS_PER_MUTANT:
                slow.append((name, seconds))
            if peak > PEAK_BYTES_PER_MUTANT:
                big.append((name, peak))
            path.unlink()
    finally:
        tracemalloc.stop()
    assert crashes == []
    assert slow == [] and big == []
    # The base file and the harmless mutants (CRLF, BOM, tabs...) are read.
    assert outcomes["read"] > 100 and outcomes["error"] > 1500, outcomes


@pytest.mark.parametrize(("value", "words"), [
    ("1e-310", "between 0.001 and 1 s"), ("1e-9", "between 0.001 and 1 s"),
    ("1e6", "between 0.001 and 1 s"), ("1e308", "between 0.001 and 1 s"),
    ("0.0009", "1-1000 frames per second"), ("1.01", "fix the frame time"),
])
def test_implausible_frame_times_are_refused(tmp_path, value, words):
    path = write_bvh(base_motion(), tmp_path / "clip.bvh")
    text = path.read_text().replace("Frame Time: 0.0333333333", f"Frame Time: {value}")
    path.write_text(text)
    with pytest.raises(BVHError, match=words) as info:
        read_bvh(path)
    assert info.value.line == text.splitlines().index(f"Frame Time: {value}") + 1


@pytest.mark.parametrize("value", ["0.001", "1"])
def test_frame_rate_limits_are_inclusive(tmp_path, value):
    path = write_bvh(base_motion(), tmp_path / "clip.bvh")
    path.write_text(path.read_text().replace("Frame Time: 0.0333333333", f"Frame Time: {value}"))
    assert read_bvh(path).fps == 1.0 / float(value)


def test_deep_nesting_is_read_without_recursion_up_to_the_joint_limit(tmp_path):
    path = tmp_path / "deep.bvh"
    path.write_text(deep_chain(limits.MAX_JOINTS))
    assert read_bvh(path).skeleton.num_joints == limits.MAX_JOINTS
    path.write_text(deep_chain(limits.MAX_JOINTS + 1))
    with pytest.raises(BVHError, match="at most 1024 are read"):
        read_bvh(path)


@pytest.mark.parametrize(("frames", "words"), [
    ("1000001", "at most 1,000,000 frames"), ("300000", "only 5 follow"),
    ("999999", "at most 20,000,000 are read"),
])
def test_frame_count_is_checked_before_allocating(tmp_path, frames, words):
    path = write_bvh(base_motion(), tmp_path / "clip.bvh")
    path.write_text(path.read_text().replace("Frames: 5", f"Frames: {frames}"))
    tracemalloc.start()
    try:
        with pytest.raises(BVHError, match=words):
            read_bvh(path)
        assert tracemalloc.get_traced_memory()[1] < 20 * 2**20
    finally:
        tracemalloc.stop()


def test_values_array_size_is_guarded():
    assert limits.size_problem(1000, 120, 20) is None
    assert "values" in limits.size_problem(600_000, 6 * 1024, 1024)


@pytest.mark.parametrize(("scale", "words"), [("1e6", "joint offsets reach"),
                                              ("1e306", "at most 1000 m")])
def test_huge_offsets_are_refused(tmp_path, scale, words):
    path = write_bvh(base_motion(), tmp_path / "clip.bvh")
    path.write_text(path.read_text().replace("OFFSET 0 95 0", f"OFFSET 0 {scale} 0"))
    with pytest.raises(BVHError, match=words):
        read_bvh(path)


def test_huge_positions_and_angles_are_refused(tmp_path):
    path = write_bvh(base_motion(), tmp_path / "clip.bvh")
    lines = path.read_text().splitlines()
    good = list(lines)
    row = lines.index("Frame Time: 0.0333333333") + 2
    values = lines[row].split()
    lines[row] = " ".join(["1e7", *values[1:]])
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(BVHError, match="position channels reach 1e"):
        read_bvh(path)
    good[row] = " ".join([*values[:3], "1e9", *values[4:]])
    path.write_text("\n".join(good) + "\n")
    with pytest.raises(BVHError, match="rotation of 1e"):
        read_bvh(path)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes need POSIX")
def test_a_named_pipe_is_refused_at_once(tmp_path):
    fifo = tmp_path / "pipe.bvh"
    os.mkfifo(fifo)
    result: list[BaseException | None] = []

    def read() -> None:
        try:
            read_bvh(fifo)
        except BaseException as exc:
            result.append(exc)
        else:
            result.append(None)

    worker = threading.Thread(target=read, daemon=True)
    worker.start()
    worker.join(5.0)
    if worker.is_alive():
        # Unblock the reader so the test process can end, then fail.
        with open(fifo, "w"):
            pass
        pytest.fail("read_bvh blocked on a named pipe")
    assert isinstance(result[0], BVHError) and "not a regular file" in str(result[0])


def test_a_device_is_refused(tmp_path):
    if not Path("/dev/zero").exists():
        pytest.skip("no /dev/zero")
    with pytest.raises(BVHError, match="not a regular file"):
        read_bvh("/dev/zero")


class TestUnits:
    @pytest.mark.parametrize("unit", sorted(limits.UNITS))
    def test_each_unit_is_detected_from_the_height(self, tmp_path, unit):
        motion = base_motion()
        back = read_bvh(write_bvh(motion, tmp_path / "clip.bvh", unit=unit))
        assert back.metadata["file_unit"] == unit
        np.testing.assert_allclose(back.skeleton.offsets, motion.skeleton.offsets, atol=1e-6)

    def test_millimetre_file_is_not_a_giant(self, tmp_path):
        back = read_bvh(write_bvh(base_motion(), tmp_path / "clip.bvh", unit="mm"))
        height = limits.figure_height(back.skeleton.offsets, back.skeleton.parents,
                                      back.skeleton.end_site_parents,
                                      back.skeleton.end_site_offsets)
        assert 1.2 <= height <= 2.2

    @pytest.mark.parametrize("forced", ["mm", "m", "in"])
    def test_a_file_read_with_a_forced_unit_re_reads_the_same(self, tmp_path, forced):
        path = write_bvh(base_motion(), tmp_path / "clip.bvh", unit="cm")
        forced_motion = read_bvh(path, unit=forced)
        written = write_bvh(forced_motion, tmp_path / "again.bvh")
        if forced == "m":
            # A 181 m giant, written in millimetres: read back only with that unit given.
            with pytest.raises(BVHError, match=r"181 m tall.*--unit"):
                read_bvh(written)
            again = read_bvh(written, unit="mm")
        else:
            again = read_bvh(written)
        assert again.skeleton.same_as(forced_motion.skeleton)
        np.testing.assert_allclose(again.positions, forced_motion.positions, atol=1e-9)

    def test_detection_gap_between_inches_and_centimetres_goes_to_centimetres(self):
        assert limits.detect_unit(100.0) == "cm"
        assert limits.detect_unit(70.0) == "in"
        assert limits.detect_unit(1.7) == "m" and limits.detect_unit(1700.0) == "mm"
        assert limits.detect_unit(0.0) == "m"


ZERO_FRAMES = "MOTION\nFrames: 0\nFrame Time: 0.0333333\n"


def test_every_bandai_clip_keeps_centimetres(bandai1_dir, bandai2_dir, tmp_path):
    header = tmp_path / "header.bvh"
    for folder in (bandai1_dir, bandai2_dir):
        for path in sorted((folder / "data").glob("*.bvh")):
            text = path.read_text()
            # The hierarchy alone decides the unit: read it without the frames.
            header.write_text(text[: text.index("MOTION")] + ZERO_FRAMES)
            motion = read_bvh(header)
            sk = motion.skeleton
            assert motion.metadata["file_unit"] == "cm", path.name
            height_m = limits.figure_height(
                sk.offsets, sk.parents, sk.end_site_parents, sk.end_site_offsets
            )
            assert limits.detect_unit(height_m / limits.UNITS["mm"]) == "mm", path.name
            assert limits.detect_unit(height_m / limits.UNITS["in"]) == "in", path.name


CLI_SAMPLE = [m for n, m in enumerate(mutants()) if n % 73 == 0 or m[0].startswith("frame_time")]


@pytest.mark.parametrize("command", ["info", "features", "classify"])
def test_cli_mutants_give_one_error_line_or_succeed(monkeypatch, capsys, tmp_path, command):
    monkeypatch.chdir(tmp_path)
    failed = succeeded = 0
    for name, data in CLI_SAMPLE[:: 3 if command == "classify" else 1]:
        path = tmp_path / f"{name}.bvh"
        path.write_bytes(data)
        extra = ["-o", tmp_path / "features.csv"] if command == "features" else []
        code, out, err = run_main(monkeypatch, capsys, command, path, *extra)
        assert "Traceback" not in err + out, (name, err)
        if code == 0:
            assert_plausible(read_bvh(path))
            succeeded += 1
        else:
            failed += 1
            assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, (name, err)
            assert not (tmp_path / "features.csv").exists(), name
        for made in (path, tmp_path / "features.csv"):
            made.unlink(missing_ok=True)
    assert failed > 0 and succeeded > 0


GB = 10**9


def sparse_file(path: Path, head: bytes, size: int = GB) -> Path:
    """``head`` followed by zero bytes up to ``size`` bytes, as a sparse file.

    The reader refuses each of these files within ``head``, so what follows it (zeros here,
    real text in the files of the issue) is never read: it behaves as on the written file.
    """
    with open(path, "wb") as fh:
        fh.write(head)
        fh.truncate(size)
    return path


def read_refused(path: Path, words: str) -> BVHError:
    """The BVHError of reading ``path``, checked to match ``words`` and to stay small."""
    tracemalloc.start()
    try:
        with pytest.raises(BVHError, match=words) as info:
            read_bvh(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 30 * 2**20, peak
    assert "\n" not in str(info.value) and len(info.value.problem) <= MAX_PROBLEM_CHARS
    return info.value


ONE_JOINT = ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n"
             "  End Site\n  {\n    OFFSET 0 170 0\n  }\n}\nMOTION\nFrames: 1\n"
             "Frame Time: 0.0333333\n")


class TestBudgets:
    """The three 1 GB files of the hardening campaign, refused before they are read whole."""

    def test_a_gigabyte_of_one_token(self, tmp_path):
        path = sparse_file(tmp_path / "token.bvh", b"x" * (3 * limits.MAX_LINE_CHARS))
        err = read_refused(path, "longer than 1,048,576 characters")
        assert err.line == 1 and path.stat().st_size == GB

    def test_a_gigabyte_row_of_three_channels(self, tmp_path):
        head = ONE_JOINT.encode() + b"0 " * (2 * limits.MAX_LINE_CHARS)
        err = read_refused(sparse_file(tmp_path / "row.bvh", head),
                           "more than the 3 values the hierarchy's channels declare")
        assert err.line == ONE_JOINT.count("\n") + 1

    def test_59_million_values_are_refused_from_the_header(self, tmp_path):
        text = base_text()
        width = len(text.splitlines()[-1].split())
        frames = 59_000_000 // width
        head = text.replace(f"Frames: {N_FRAMES}", f"Frames: {frames}").encode()
        err = read_refused(sparse_file(tmp_path / "values.bvh", head),
                           f"{frames:,} frames x {width} channels .* at most 20,000,000")
        assert err.line == text.splitlines().index(f"Frames: {N_FRAMES}") + 1

    def test_a_file_at_the_values_limit_is_read_and_one_above_is_not(self, tmp_path,
                                                                     monkeypatch):
        motion = base_motion(frames=12)
        path = write_bvh(motion, tmp_path / "clip.bvh")
        width = len(path.read_text().splitlines()[-1].split())
        monkeypatch.setattr(input_limits, "MAX_VALUES", 12 * width)
        assert read_bvh(path).num_frames == 12
        monkeypatch.setattr(input_limits, "MAX_VALUES", 12 * width - 1)
        with pytest.raises(BVHError, match=f"= {12 * width} values: at most"):
            read_bvh(path)

    def test_a_row_within_its_width_but_over_the_line_limit(self, tmp_path, monkeypatch):
        monkeypatch.setattr(limits, "MAX_LINE_CHARS", 1000)
        path = tmp_path / "spaces.bvh"
        path.write_text(ONE_JOINT + "0" + " " * 1000 + "0 0\n")
        with pytest.raises(BVHError, match="longer than 1,000 characters"):
            read_bvh(path)
        path.write_text(ONE_JOINT + "0" + " " * 990 + "0 0\n")
        assert read_bvh(path).num_frames == 1

    def test_a_word_over_the_token_limit(self, tmp_path):
        text = base_text()
        path = tmp_path / "name.bvh"
        path.write_text(text.replace("Spine", "S" * (limits.MAX_TOKEN_CHARS + 1)))
        err = read_refused(path, "a word of 257 characters, 'SSS.*' .* at most 256")
        assert err.line == 6
        path.write_text(text.replace("Spine", "S" * limits.MAX_TOKEN_CHARS))
        assert "S" * limits.MAX_TOKEN_CHARS in read_bvh(path).skeleton.names

    def test_end_sites_are_bounded_like_joints(self, tmp_path, monkeypatch):
        monkeypatch.setattr(input_limits, "MAX_JOINTS", 3)
        end = "End Site\n{\nOFFSET 0 1 0\n}\n"
        path = tmp_path / "ends.bvh"
        path.write_text(ONE_JOINT.replace("  End Site", end * 3 + "  End Site"))
        with pytest.raises(BVHError, match="more than 3 end sites"):
            read_bvh(path)
        path.write_text(ONE_JOINT.replace("  End Site", end * 2 + "  End Site") + "0 0 0\n")
        assert read_bvh(path).skeleton.end_site_offsets.shape == (3, 3)


class TestQuotes:
    @pytest.mark.parametrize(("frames", "words"), [
        ("1" * 5000, "whole number >= 0"), ("1" * 4000, "at most 1,000,000 frames"),
    ])
    def test_a_long_frame_count_is_quoted_short(self, tmp_path, frames, words):
        path = write_bvh(base_motion(), tmp_path / "clip.bvh")
        path.write_text(path.read_text().replace(f"Frames: {N_FRAMES}", f"Frames: {frames}"))
        with pytest.raises(BVHError, match=words) as info:
            read_bvh(path)
        quoted = f"'{'1' * 77}...' ({len(frames):,} characters)"
        assert quoted in info.value.problem and "1" * 78 not in info.value.problem

    def test_a_long_value_in_the_frames_is_quoted_short(self, tmp_path):
        path = write_bvh(base_motion(), tmp_path / "clip.bvh")
        lines = path.read_text().splitlines()
        lines[-2] = " ".join(["y" * 5000, *lines[-2].split()[1:]])
        path.write_text("\n".join(lines) + "\n")
        with pytest.raises(BVHError, match=r"non-numeric value 'y{77}\.\.\.' \(5,000 characters\)"):
            read_bvh(path)

    def test_quote(self):
        assert limits.quote("abc") == "'abc'"
        assert limits.quote("a" * 80) == f"'{'a' * 80}'"
        assert limits.quote("a" * 81) == f"'{'a' * 77}...' (81 characters)"


class TestHeightBound:
    @pytest.mark.parametrize(("scale", "words"), [
        (100.0, r"stands 1\d\.\d m tall with its unit detected as 'mm'"),
        (1e-4, r"stands 0\.01\d\d m tall with its unit detected as 'm'"),
    ])
    def test_an_implausible_figure_is_refused_unless_its_unit_is_given(
            self, tmp_path, monkeypatch, capsys, scale, words):
        # A 170 m figure written in centimetres (17,000 units) is detected as millimetres
        # (17 m); a 0.17 mm figure (0.017 units) as metres.
        motion = base_motion()
        sk = motion.skeleton.scaled(scale)
        scaled = motion.replace(skeleton=sk, positions=motion.positions * scale)
        path = write_bvh(scaled, tmp_path / "clip.bvh", unit="cm")
        with pytest.raises(BVHError, match=f"{words}: 0.05-10 m is plausible.*--unit"):
            read_bvh(path)
        assert read_bvh(path, unit="cm").skeleton.same_as(sk)
        monkeypatch.chdir(tmp_path)
        code, _, err = run_main(monkeypatch, capsys, "info", path)
        assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, err
        assert "--unit" in err
        code, _, err = run_main(monkeypatch, capsys, "info", path, "--unit", "cm")
        assert code == 0, err

    def test_the_bounds_are_inclusive_and_apply_to_a_detected_unit(self):
        low, high = limits.PLAUSIBLE_HEIGHT_M
        assert limits.height_problem(low, "m") is None
        assert limits.height_problem(high, "mm") is None
        assert "'cmu'" in limits.height_problem(high * 1.01, "cmu")
        assert limits.height_problem(low * 0.99, "m") is not None
