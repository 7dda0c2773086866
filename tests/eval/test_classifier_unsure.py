"""The committed classifier says "unsure" off its training data, and not on held-out walks."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from emotive.cli import main
from emotive.core.motion import Motion
from emotive.data.clips import list_clips
from emotive.data.splits import split_clips
from emotive.eval.classifier import (
    Judgement,
    load_default_classifier,
    role_track,
    track_features,
)
from emotive.eval.classifier_probes import joint_noise, spinning_figure
from emotive.io.bvh import read_bvh, write_bvh
from emotive.transforms.np_rotations import euler_to_quaternion, quaternion_multiply


@pytest.fixture(scope="module")
def model():
    return load_default_classifier()


def spinning(motion: Motion, seconds: float = 6.0, turns_per_second: float = 1.0) -> Motion:
    """The clip's first pose held still while the hips turn about the vertical axis."""
    frames = round(seconds * motion.fps)
    hips = motion.skeleton.names.index("Hips")
    rotations = np.repeat(motion.rotations[:1], frames, 0)
    positions = np.repeat(motion.positions[:1], frames, 0)
    yaw = 2 * np.pi * turns_per_second * np.arange(frames) / motion.fps
    turn = euler_to_quaternion(np.stack((np.zeros(frames), yaw, np.zeros(frames)), -1), "XYZ")
    rotations[:, hips] = quaternion_multiply(turn, rotations[:, hips])
    return motion.replace(rotations=rotations, positions=positions)


def held_out(dataset: str, count: int = 3) -> list:
    test = split_clips(list_clips(dataset, locomotion=True))["test"]
    return [read_bvh(c.path) for c in test[::max(1, len(test) // count)][:count]]


@pytest.mark.data
@pytest.mark.parametrize("dataset", ["bandai-namco-1", "bandai-namco-2-locomotion"])
def test_held_out_walks_are_not_unsure(model, dataset, bandai1_dir, bandai2_dir):
    for motion in held_out(dataset):
        judged = model.judge(motion)
        assert not judged.clip_unsure
        assert judged.unsure.mean() <= 0.25
        assert np.all(judged.probabilities.max(-1) <= 1.0)


@pytest.mark.data
def test_a_spinning_figure_and_joint_noise_are_unsure(model, bandai1_dir):
    walk = read_bvh(bandai1_dir / "data" / "dataset-1_walk_normal_001.bvh")
    spin = spinning(walk)
    # The hips turned: the figure faces every way in a second, in place.
    track = role_track(spin)
    assert np.ptp(track[:, 0, [0, 2]], axis=0).max() < 0.01
    judged = model.judge(spin)
    assert judged.clip_unsure and judged.unsure.all()
    assert set(judged.perceived) == {"unsure"}
    # The same from the probe module's role-level spin, and from random joint noise.
    for points in (spinning_figure(role_track(walk)[0], 30.0, 6.0),
                   joint_noise(np.random.default_rng(0), 180)):
        out = model.outputs(model.windows(track_features(points, 30.0, model.config), 4.0,
                                          1.0)[1])
        assert out["unsure"].all()
        assert (out["distance"] > model.unsure_distance).all()


@pytest.mark.data
def test_cli_prints_unsure(model, bandai1_dir, tmp_path, monkeypatch, capsys):
    walk = read_bvh(bandai1_dir / "data" / "dataset-1_walk_normal_001.bvh")
    clip = write_bvh(spinning(walk), tmp_path / "spin.bvh")
    monkeypatch.setenv("COLUMNS", "200")
    monkeypatch.setattr(sys, "argv", ["emotive", "classify", str(clip)])
    with pytest.raises(SystemExit) as exc:
        main()
    assert exc.value.code in (0, None)
    out = capsys.readouterr().out
    assert "unsure:" in out and "lie outside the motion the classifier was trained on" in out
    monkeypatch.setattr(sys, "argv", ["emotive", "classify", str(clip), "--json"])
    with pytest.raises(SystemExit) as exc:
        main()
    result = json.loads(capsys.readouterr().out)
    assert result["unsure"] is True and result["perceived"] == "unsure"
    assert all(w["unsure"] and w["perceived"] == "unsure" for w in result["windows"])
    monkeypatch.setattr(sys, "argv", ["emotive", "classify", str(clip), "--window", "0.5"])
    with pytest.raises(SystemExit) as exc:
        main()
    err = capsys.readouterr().err
    assert exc.value.code != 0 and "at least 0.8 s" in err and "6.00 s" in err


@pytest.mark.parametrize(("unsure", "expected"), [
    ([True, False], False),                      # exactly half: not most
    ([True, True, False, False], False),
    ([True, True, False], True),                 # one more than half
    ([True, True, True, False, False], True),
    ([False, False, False], False),
    ([True], True),
])
def test_a_clip_is_unsure_when_most_of_its_windows_are(unsure, expected):
    k = len(unsure)
    judgement = Judgement(times=np.arange(k, dtype=float), probabilities=np.full((k, 2), 0.5),
                          valence_arousal=np.zeros((k, 2)), distance=np.zeros(k),
                          unsure=np.array(unsure), labels=("happy", "sad"))
    assert judgement.clip_unsure is expected
