"""The perceived-emotion classifier: features, network, files, CLI and the committed model."""

from __future__ import annotations

import json
import sys
from dataclasses import replace

import numpy as np
import pytest
import torch

from emotive.cli import main
from emotive.core.roles import resolve_roles
from emotive.eval.classifier import (
    NUM_FEATURES,
    ClassifierConfig,
    ClassifierError,
    EmotionClassifier,
    EmotionClassifierNet,
    default_classifier_path,
    frame_features,
    load_default_classifier,
)
from emotive.io.bvh import read_bvh, write_bvh


@pytest.fixture
def walk(bandai1_dir):
    return read_bvh(bandai1_dir / "data" / "dataset-1_walk_happy_002.bvh")


def untrained(seed: int = 0) -> EmotionClassifier:
    config = ClassifierConfig(seed=seed)
    torch.manual_seed(seed)
    return EmotionClassifier(config, EmotionClassifierNet(config).eval(),
                             np.zeros(NUM_FEATURES, np.float32), np.ones(NUM_FEATURES, np.float32))


@pytest.mark.data
def test_features_ignore_where_the_walker_is_how_it_faces_and_its_size(walk):
    roles = resolve_roles(walk.skeleton)
    p = walk.positions_with_end_sites()
    base = frame_features(p, roles, walk.fps, 15.0)
    assert base.shape == (round(walk.num_frames / 2), NUM_FEATURES)
    assert np.isfinite(base).all()
    a = 1.1
    turn = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    moved = 1.7 * (p @ turn.T) + [3.0, 0.0, -2.0]
    np.testing.assert_allclose(frame_features(moved, roles, walk.fps, 15.0), base, atol=2e-4)


def test_any_window_length_gives_probabilities():
    model = untrained()
    rng = np.random.default_rng(0)
    for length in (30, 45, 150):
        prob = model.predict_features(rng.normal(size=(3, length, NUM_FEATURES)))
        assert prob.shape == (3, 4)
        np.testing.assert_allclose(prob.sum(-1), 1.0, rtol=1e-5)
    assert model.predict_features(rng.normal(size=(30, NUM_FEATURES))).shape == (4,)


def test_save_load_round_trip(tmp_path):
    model = untrained(seed=3)
    model.metrics = {"test": {"window_accuracy": 0.5}}
    path = model.save(tmp_path / "c.pt")
    back = EmotionClassifier.load(path)
    assert back.config == model.config and back.metrics == model.metrics
    x = np.random.default_rng(1).normal(size=(2, 40, NUM_FEATURES))
    np.testing.assert_array_equal(back.predict_features(x), model.predict_features(x))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.pt"]


def test_bad_files(tmp_path):
    with pytest.raises(ClassifierError, match="does not exist"):
        EmotionClassifier.load(tmp_path / "none.pt")
    broken = tmp_path / "broken.pt"
    broken.write_bytes(b"not a checkpoint")
    with pytest.raises(ClassifierError, match="not a valid emotive classifier"):
        EmotionClassifier.load(broken)
    other = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(3)}, other)
    with pytest.raises(ClassifierError, match="not a valid emotive classifier"):
        EmotionClassifier.load(other)


@pytest.mark.data
def test_classify_windows_and_too_short_clips(walk):
    model = untrained()
    # 4.5 s at 15 fps: 68 feature frames; 30-frame windows every 9 frames start at 0..36.
    times, prob = model.classify(walk, window_seconds=2.0, hop_seconds=0.6)
    assert prob.shape == (len(times), 4) and len(times) == 5
    np.testing.assert_allclose(np.diff(times), 0.6)
    np.testing.assert_allclose(times[0], 1.0)
    short = walk.replace(rotations=walk.rotations[:40], positions=walk.positions[:40])
    with pytest.raises(ClassifierError, match="at least 2 s"):
        model.classify(short)


def test_committed_classifier_and_card():
    model = load_default_classifier()
    assert model.labels == ("happy", "sad", "angry", "neutral")
    for key in ("test", "val", "cross_validation"):
        result = model.metrics[key]
        assert 0.0 <= result["window_accuracy"] <= 1.0
        assert np.array(result["confusion"]).sum() == result["windows"]
    card = (default_classifier_path().parent / "MODEL_CARD.md").read_text()
    assert "CC BY-NC 4.0" in card
    assert f"{model.metrics['test']['window_accuracy']:.3f}" in card
    assert f"{model.metrics['cross_validation']['window_accuracy']:.3f}" in card


@pytest.mark.data
def test_retraining_reproduces_the_committed_accuracy(bandai1_dir):
    """Same recipe, same seed: the held-out numbers match the committed model's within 2
    windows (float differences between CPUs can flip a near-tie)."""
    from emotive.eval.classifier_training import train_classifier

    committed = load_default_classifier()
    fresh = train_classifier(replace(committed.config))
    for split in ("val", "test"):
        ours, theirs = fresh.metrics[split], committed.metrics[split]
        assert ours["windows"] == theirs["windows"]
        assert abs(ours["window_accuracy"] - theirs["window_accuracy"]) <= 2 / ours["windows"]


@pytest.mark.data
def test_cli_table_and_json(walk, tmp_path, monkeypatch, capsys):
    clip = write_bvh(walk, tmp_path / "walk.bvh")
    monkeypatch.setenv("COLUMNS", "160")
    for extra in ([], ["--json"]):
        monkeypatch.setattr(sys, "argv", ["emotive", "classify", str(clip), *extra])
        with pytest.raises(SystemExit) as exc:
            main()
        assert exc.value.code in (0, None)
        out = capsys.readouterr().out
        if extra:
            result = json.loads(out)
            assert result["labels"] == ["happy", "sad", "angry", "neutral"]
            assert abs(sum(result["mean"].values()) - 1.0) < 1e-5
            assert result["perceived"] in result["labels"]
        else:
            assert "perceived emotion of walk.bvh" in out and "mean" in out
    monkeypatch.setattr(sys, "argv", ["emotive", "classify", str(clip), "--model",
                                      str(tmp_path / "missing.pt")])
    with pytest.raises(SystemExit) as exc:
        main()
    assert exc.value.code == 2 and "does not exist" in capsys.readouterr().err
