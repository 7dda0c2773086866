"""Tests of ``emotive transfer`` on a synthetic index and synthetic BVH clips (no data needed)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from emotive.commands.transfer import transfer
from emotive.errors import BVHError, EmotionError, OutputError
from emotive.io.bvh import read_bvh, write_bvh
from emotive.models.mar.config import TransferError
from emotive.models.mar.representation import RigMappingError

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "models" / "mar"))
from mar_helpers import CONFIG, examples, styled

from cli_helpers import assert_failed_cleanly, invoke_command, nan_copy


@pytest.fixture(scope="module")
def synthetic_index(tmp_path_factory) -> Path:
    """The synthetic database (every take but the second) saved as an index file."""
    from emotive.models.mar.build import build_database

    held = tuple(f"synthetic_walk_{s}_2" for s in ("neutral", "proud", "sad"))
    db = build_database(examples(3, skip=held), CONFIG)
    return db.save(tmp_path_factory.mktemp("index") / "index.npz")


@pytest.fixture
def walk_file(tmp_path: Path) -> Path:
    return write_bvh(styled("walk", "neutral", take=2), tmp_path / "walk.bvh", unit="cm")


def invoke(*args: object):
    """Run ``transfer`` with ``args``."""
    return invoke_command("transfer", transfer, *args)


def test_a_clip_is_written_in_the_new_style_on_its_own_rig(walk_file, synthetic_index, tmp_path):
    out, video = tmp_path / "proud.bvh", tmp_path / "proud.gif"
    result = invoke(walk_file, "--style", "proud=0.6,sad=0.4", "--out", out, "--index",
                    synthetic_index, "--rho", "0.5", "--action", "walk", "--preview", video)
    assert result.exit_code == 0, result.output
    before, after = read_bvh(walk_file), read_bvh(out)
    assert after.skeleton.names == before.skeleton.names
    assert after.skeleton.channels == before.skeleton.channels
    assert after.fps == before.fps and after.num_frames > before.num_frames
    assert video.stat().st_size > 0
    line = [ln for ln in result.stdout.splitlines() if ln.strip()]
    assert len(line) == 1 and line[0].startswith(f"wrote {out}: 90 frames -> ")
    assert "style proud=0.6,sad=0.4" in line[0] and "ms/frame" in line[0]


def test_a_style_schedule_file_drives_the_style(walk_file, synthetic_index, tmp_path):
    schedule = tmp_path / "schedule.json"
    # Neutral held for the first second, then a blend to sad at 2 s (the schedule interpolates
    # linearly between keys).
    schedule.write_text(json.dumps([{"t": 0, "emotion": "neutral"}, {"t": 1, "emotion": "neutral"},
                                    {"t": 2, "emotion": "sad"}]))
    out = tmp_path / "out.bvh"
    result = invoke(walk_file, "--style-schedule", schedule, "--out", out, "--index",
                    synthetic_index)
    assert result.exit_code == 0, result.output
    from emotive.transforms.np_rotations import quaternion_to_axis_angle

    chest = quaternion_to_axis_angle(read_bvh(out).rotations[:, 2])[:, 0]
    assert chest[:20].mean() == pytest.approx(0.0, abs=0.05)
    assert chest[-15:].mean() > 0.25


@pytest.mark.parametrize(
    ("case", "error", "words"),
    [
        ("style", EmotionError, ("--style", "prout", "did you mean 'proud'")),
        ("rig", RigMappingError, ("renamed.bvh", "--roles")),
        ("short", TransferError, ("short.bvh", "2 frames", "at least 3")),
        ("nan", BVHError, ("nan.bvh", "NaN")),
        ("suffix", OutputError, ("--out", "use a file ending in .bvh")),
        ("action", TransferError, ("walk.bvh", "unknown action 'jump'", "walk, wave")),
        ("both", EmotionError, ("walk.bvh", "exactly one of --style and --style-schedule")),
        ("index", TransferError, ("missing.npz", "--build-index")),
    ],
)
def test_bad_input_fails_in_one_line_without_output(
    walk_file, synthetic_index, tmp_path, case, error, words
):
    out = tmp_path / "out.bvh"
    args: list[object] = [walk_file, "--style", "proud", "--out", out, "--index", synthetic_index]
    if case == "style":
        args[2] = "prout"
    elif case == "rig":
        args[0] = write_bvh(styled("walk", "neutral", 2, rename={"UpperLeg_L": "thigh"}),
                            tmp_path / "renamed.bvh", unit="cm")
        args += ["--roles", "bandai"]  # without a map the rig's shape would name the roles
    elif case == "short":
        motion = styled("walk", "neutral", 2, frames=2)
        args[0] = write_bvh(motion, tmp_path / "short.bvh", unit="cm")
    elif case == "nan":
        args[0] = nan_copy(walk_file)
    elif case == "suffix":
        args[4] = tmp_path / "out.txt"
    elif case == "action":
        args += ["--action", "jump"]
    elif case == "both":
        args += ["--style-schedule", tmp_path / "s.json"]
    elif case == "index":
        args[-1] = tmp_path / "missing.npz"
    before = sorted(tmp_path.iterdir())
    result = invoke(*args)
    assert_failed_cleanly(result, error, words, tmp_path, before)


def test_the_index_is_built_in_the_cache_on_request(tmp_path, monkeypatch):
    from emotive.models.mar import database, default_index

    monkeypatch.setenv("EMOTIVE_HOME", str(tmp_path / "home"))
    monkeypatch.setattr(default_index, "clip_examples", lambda config: examples(2))
    result = invoke("--build-index")
    assert result.exit_code == 0, result.output
    built = list((tmp_path / "home" / "mar").glob("index-*.npz"))
    assert len(built) == 1 and f"index ready: {built[0]}" in result.stdout
    db = database.MARDatabase.load(built[0])
    assert db.num_frames > 0 and db.styles == ("neutral", "proud", "sad")
    assert isinstance(invoke().exception, OutputError)


def test_the_console_entry_point_prints_one_error_line(tmp_path, monkeypatch, capsys):
    from emotive import cli

    out = tmp_path / "out.bvh"
    monkeypatch.setattr(sys, "argv", ["emotive", "transfer", str(tmp_path / "missing.bvh"),
                                      "--style", "proud", "--out", str(out)])
    with pytest.raises(SystemExit) as exc:
        cli.main()
    assert exc.value.code != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "missing.bvh" in err[0]
    assert not out.exists()
