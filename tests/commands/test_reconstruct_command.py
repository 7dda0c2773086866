"""Tests of ``emotive reconstruct`` on a synthetic walk written as BVH (no data needed)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from cli_helpers import assert_failed_cleanly, invoke_command, nan_copy
from emotive.commands.reconstruct import reconstruct, summary
from emotive.core import Motion, Skeleton
from emotive.errors import BVHError, OutputError, RigError
from emotive.io.bvh import read_bvh, write_bvh
from emotive.transforms.np_rotations import axis_angle_to_quaternion
from rigs import RIG

FRAMES = 45
#: World end effectors and elbows of the rebuilt file against the input, metres (measured:
#: under 0.2 mm).
EFFECTOR_TOL = 2e-3
#: Every joint and end site, metres (measured: under 1 mm; on real clips the legs' free knee
#: swivel allows a few centimetres, see ``tests/ik/test_api.py``).
JOINT_TOL = 1e-2


def make_walk(rename: dict[str, str] | None = None) -> Motion:
    """1.5 s at 30 fps on :data:`RIG`: the root moves forward at 1 m/s, legs swing with bent
    knees, arms hang with bent elbows and swing, the spine twists."""
    rename = rename or {}
    names = tuple(rename.get(r[0], r[0]) for r in RIG)
    ends = [(j, r[3]) for j, r in enumerate(RIG) if r[3] is not None]
    sk = Skeleton(
        names,
        np.array([r[1] for r in RIG]),
        np.array([r[2] for r in RIG], dtype=float),
        end_site_parents=[j for j, _ in ends],
        end_site_offsets=[o for _, o in ends],
    )
    idx = {r[0]: j for j, r in enumerate(RIG)}
    t = np.arange(FRAMES) / 30.0
    phase = 2 * np.pi * t
    aa = np.zeros((FRAMES, len(RIG), 3))
    for s, sign in (("L", 1.0), ("R", -1.0)):
        aa[:, idx[f"UpperLeg_{s}"], 0] = -0.2 + sign * 0.3 * np.sin(phase)
        aa[:, idx[f"LowerLeg_{s}"], 0] = 0.4 + 0.2 * np.cos(phase)
        aa[:, idx[f"Foot_{s}"], 0] = -0.15
        aa[:, idx[f"UpperArm_{s}"], 0] = -sign * 0.3 * np.sin(phase)
        aa[:, idx[f"UpperArm_{s}"], 2] = sign * 0.15
        aa[:, idx[f"LowerArm_{s}"], 0] = -0.5 - 0.1 * np.sin(phase)
    aa[:, idx["Spine"], 1] = 0.1 * np.sin(phase)
    aa[:, idx["Neck"], 0] = 0.1
    rotations = axis_angle_to_quaternion(aa)
    positions = np.broadcast_to(sk.offsets, (FRAMES, len(RIG), 3)).copy()
    positions[:, 0, 2] += 1.0 * t
    return Motion(sk, rotations, positions, 30.0)


@pytest.fixture
def walk_file(tmp_path: Path) -> Path:
    return write_bvh(make_walk(), tmp_path / "walk.bvh", unit="cm")


def invoke(*args: object):
    """Run ``reconstruct`` with ``args``."""
    return invoke_command("reconstruct", reconstruct, *args)


def test_round_trip_writes_the_input_rig_close_to_the_input(walk_file, tmp_path):
    out, video = tmp_path / "rebuilt.bvh", tmp_path / "rebuilt.gif"
    result = invoke(walk_file, "--out", out, "--preview", video)
    assert result.exit_code == 0, result.output
    assert video.stat().st_size > 0
    before, after = read_bvh(walk_file), read_bvh(out)
    assert after.skeleton.names == before.skeleton.names
    assert after.skeleton.channels == before.skeleton.channels
    np.testing.assert_allclose(after.skeleton.offsets, before.skeleton.offsets, atol=1e-9)
    assert after.num_frames == before.num_frames == FRAMES and after.fps == before.fps
    a, b = before.positions_with_end_sites(), after.positions_with_end_sites()
    from emotive.ik import resolve_chains

    for name, chain in resolve_chains(before.skeleton, before).items():
        err = np.linalg.norm(a[:, chain.targets] - b[:, chain.targets], axis=-1).max()
        assert err < EFFECTOR_TOL, (name, err)
    assert np.linalg.norm(a - b, axis=-1).max() < JOINT_TOL
    lines = [ln for ln in result.stdout.splitlines() if ln.strip()]
    assert len(lines) == 1
    line = lines[0]
    assert line.startswith(f"wrote {out}: {FRAMES} frames (1.50 s) rebuilt in ")
    for part in (
        "ms/frame",
        "target residual mean/max mm: head_torso ",
        "left_arm",
        "right_leg",
        "unreachable targets clamped: none",
    ):
        assert part in line


def test_a_role_map_file_rebuilds_a_renamed_rig(tmp_path):
    renamed = write_bvh(
        make_walk({"Hips": "pelvis", "LowerArm_L": "forearm_l"}),
        tmp_path / "renamed.bvh",
        unit="cm",
    )
    out = tmp_path / "rebuilt.bvh"
    # Without --roles the rig's shape would name every role; the Bandai names do not.
    result = invoke(renamed, "--out", out, "--roles", "bandai")
    assert isinstance(result.exception, RigError) and not out.exists()
    message = str(result.exception)
    assert str(renamed) in message and "--roles" in message and "\n" not in message
    from emotive.core.roles import BANDAI

    role_map = tmp_path / "roles.json"
    role_map.write_text(json.dumps({**BANDAI, "root": "pelvis", "l_elbow": "forearm_l"}))
    result = invoke(renamed, "--out", out, "--roles", role_map)
    assert result.exit_code == 0, result.output
    assert read_bvh(out).skeleton.names[0] == "pelvis"


@pytest.mark.parametrize(
    ("case", "error", "words"),
    [
        ("suffix", OutputError, ("--out", "use a file ending in .bvh")),
        ("missing", BVHError, ("missing.bvh", "does not exist")),
        ("not_bvh", BVHError, ("notes.bvh", "HIERARCHY")),
        ("nan", BVHError, ("nan.bvh", "NaN")),
        ("preview", OutputError, ("--preview", ".mp4 or .gif")),
    ],
)
def test_bad_input_fails_in_one_line_without_output(walk_file, tmp_path, case, error, words):
    out = tmp_path / "out.bvh"
    args: list[object] = [walk_file, "--out", out]
    if case == "suffix":
        out = tmp_path / "out.txt"
        args = [walk_file, "--out", out]
    elif case == "missing":
        args[0] = tmp_path / "missing.bvh"
    elif case == "not_bvh":
        args[0] = tmp_path / "notes.bvh"
        args[0].write_text("these are notes, not a motion\n")
    elif case == "nan":
        args[0] = nan_copy(walk_file)
    elif case == "preview":
        args += ["--preview", tmp_path / "p.png"]
    before = sorted(tmp_path.iterdir())
    result = invoke(*args)
    assert_failed_cleanly(result, error, words, tmp_path, before)


def test_the_console_entry_point_prints_one_error_line(tmp_path, monkeypatch, capsys):
    from emotive import cli

    # Register the command as the lead will in emotive/cli.py, without changing the real app.
    monkeypatch.setattr(cli.app, "registered_commands", list(cli.app.registered_commands))
    if not any(c.name == "reconstruct" for c in cli.app.registered_commands):
        cli.app.command("reconstruct")(reconstruct)
    out = tmp_path / "out.bvh"
    monkeypatch.setattr(
        sys, "argv", ["emotive", "reconstruct", str(tmp_path / "missing.bvh"), "--out", str(out)]
    )
    with pytest.raises(SystemExit) as exc:
        cli.main()
    assert exc.value.code != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "missing.bvh" in err[0]
    assert not out.exists()


def test_summary_reports_clamped_targets_per_chain():
    from emotive.ik import IKResult, Unreachable

    motion = make_walk()
    none = Unreachable(np.zeros(0, dtype=np.int64), (), np.zeros(0))
    clamped = Unreachable(
        np.array([3, 4, 4]), ("l_ankle", "l_ankle", "l_toe"), np.array([0.002, 0.0125, 0.001])
    )
    result = IKResult(
        motion,
        {"head_torso": np.full(FRAMES, 1e-4), "left_leg": np.zeros(FRAMES)},
        {"head_torso": none, "left_leg": clamped},
        seconds=0.9,
    )
    line = summary(result, motion.fps)
    assert "\n" not in line
    assert f"{FRAMES} frames (1.50 s) rebuilt in 0.90 s (20.0 ms/frame)" in line
    assert "head_torso 0.10/0.10, left_leg 0.00/0.00" in line
    assert line.endswith("clamped: left_leg 3 (l_ankle, l_toe; up to 12.5 mm beyond reach)")


def test_summary_reports_frames_left_off_target():
    from emotive.ik import IKResult, Unreachable

    motion = make_walk()
    none = Unreachable(np.zeros(0, dtype=np.int64), (), np.zeros(0))
    residual = np.full(FRAMES, 1e-4)
    residual[[4, 9]] = [0.02, 0.05]
    result = IKResult(motion, {"left_arm": residual}, {"left_arm": none}, seconds=0.9,
                      off_target={"left_arm": np.array([4, 9])})
    line = summary(result, motion.fps)
    assert "off target by more than 10 mm after retries: left_arm 2 (4.4 %, up to 50 mm)" in line
    assert line.endswith("unreachable targets clamped: none")
