"""Tests of ``emotive resample`` on synthetic clips standing in for the data set (no data
needed): files, reproducibility, frame rate, preview, typed one-line errors, no stray files."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from cli_helpers import assert_failed_cleanly, invoke_command
from emotive.commands.generate import generate
from emotive.errors import EmotionError, OutputError
from emotive.io.bvh import read_bvh
from emotive.models.lgb.bootstrap import LGBError, TooLittleDataError
from lgb_clips import synthetic_clip


@pytest.fixture
def fake_data(monkeypatch):
    """``load_clips`` returns synthetic clips: three sad ones, two short angry ones, and three
    happy ones, one of them holding a NaN."""
    bad = synthetic_clip(160, 5, "happy")
    rot = bad.motion.rotations.copy()
    rot[7, 2] = np.nan
    clips = [synthetic_clip(160, s) for s in range(3)]
    clips += [synthetic_clip(60, s, "angry") for s in range(2)]
    clips += [synthetic_clip(160, 5, "happy", bad.motion.replace(rotations=rot))]
    clips += [synthetic_clip(160, s, "happy") for s in (6, 7)]
    calls = []

    def load(name, **kw):
        calls.append(name)
        return clips

    monkeypatch.setattr("emotive.data.clips.load_clips", load)
    return calls


def invoke(*args: object):
    """Run ``generate --model lgb`` with ``args``."""
    return invoke_command("generate", generate, "--model", "lgb", *args)


def test_writes_a_reproducible_file_of_any_length(fake_data, tmp_path):
    a, b, c = (tmp_path / f"{k}.bvh" for k in "abc")
    result = invoke("--emotion", "sad", "--seconds", 20, "--out", a, "--seed", 3,
                    "--workers", 1)
    assert result.exit_code == 0, result.output
    assert fake_data == ["bandai-namco-1"]
    motion = read_bvh(a)
    # 600 frames from 435 captured frames: the length does not depend on the data's.
    assert motion.num_frames == 600 and motion.fps == 30.0
    assert "Shoulder_L" in motion.skeleton.names
    text = " ".join(result.output.split())
    assert "sad, seed 3: 600 frames" in text and f"wrote {a}" in text
    assert invoke("--emotion", "sad", "--seconds", 20, "--out", b, "--seed", 3,
                  "--workers", 1).exit_code == 0
    assert a.read_bytes() == b.read_bytes()
    assert invoke("--emotion", "sad", "--seconds", 20, "--out", c, "--seed", 4,
                  "--workers", 1).exit_code == 0
    assert a.read_bytes() != c.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bvh", "b.bvh", "c.bvh"]


def test_frame_rate_and_preview(fake_data, tmp_path):
    out, video = tmp_path / "sad.bvh", tmp_path / "sad.gif"
    result = invoke("-e", "sad", "--seconds", 2, "-o", out, "--fps", 24, "--preview", video,
                    "--workers", 1)
    assert result.exit_code == 0, result.output
    motion = read_bvh(out)
    assert motion.num_frames == 48 and abs(motion.fps - 24.0) < 1e-6
    assert video.stat().st_size > 0


@pytest.mark.parametrize(
    ("args", "error", "words"),
    [
        (("-e", "sda"), EmotionError, ("unknown emotion 'sda'", "did you mean 'sad'", "happy")),
        (("-e", "tired"), EmotionError, ("no clips of emotion 'tired' in bandai-namco-1",
                                         "choose one of")),
        (("-e", "angry"), TooLittleDataError, ("emotion 'angry' in bandai-namco-1 (2 clips)",
                                               "has 90 frames but at least 206 are needed",
                                               "add clips")),
        (("-e", "happy"), LGBError, ("dataset-1_walk_happy_006", "NaN", "frames (7)")),
        (("-e", "sad", "--out-suffix", ".txt"), OutputError, ("--out", ".bvh")),
    ],
)
def test_bad_input_fails_in_one_line_without_output(fake_data, tmp_path, args, error, words):
    args = list(args)
    out = tmp_path / "out.bvh"
    if "--out-suffix" in args:
        i = args.index("--out-suffix")
        out = tmp_path / f"out{args[i + 1]}"
        del args[i : i + 2]
    result = invoke(*args, "--out", out, "--workers", 1)
    assert_failed_cleanly(result, error, words, tmp_path, [])


def test_the_console_entry_point_prints_one_error_line(fake_data, tmp_path, monkeypatch,
                                                       capsys):
    from emotive import cli

    out = tmp_path / "out.bvh"
    monkeypatch.setattr(sys, "argv", ["emotive", "resample", "--emotion", "angry", "--out",
                                      str(out)])
    with pytest.raises(SystemExit) as exc:
        cli.main()
    assert exc.value.code != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and err[0] == ("deprecated: `emotive resample` is now `emotive generate "
                                        "--model lgb`; the old spelling goes in 0.3")
    assert err[1].startswith("error: ") and "206" in err[1]
    assert not out.exists()


@pytest.mark.parametrize(("cores", "load", "expected"),
                         [(2, 0.3, 2), (2, 1.5, 1), (2, 5.0, 1), (16, 0.0, 2), (1, 0.0, 1)])
def test_default_workers_are_the_idle_cores(monkeypatch, cores, load, expected):
    import os

    from emotive.models.lgb.adapter import idle_cores

    monkeypatch.setattr(os, "cpu_count", lambda: cores)
    monkeypatch.setattr(os, "getloadavg", lambda: (load, load, load))
    assert idle_cores() == expected
