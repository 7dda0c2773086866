"""The perceived-emotion classifier: features, network, files, CLI and the committed model."""

from __future__ import annotations

import json
import sys
from dataclasses import replace

import numpy as np
import pytest
import torch

from emotive.cli import main
from emotive.core.roles import ROLES, resolve_roles
from emotive.eval.classifier import (
    ARCHITECTURES,
    JOINT_COLUMNS,
    NUM_FEATURES,
    ROLE_EDGES,
    ClassifierConfig,
    ClassifierError,
    EmotionClassifier,
    EmotionClassifierNet,
    EmotionGraphNet,
    _GraphBlock,
    build_net,
    default_classifier_path,
    frame_features,
    joint_nodes,
    load_default_classifier,
    role_adjacency,
)
from emotive.io.bvh import read_bvh, write_bvh


@pytest.fixture
def walk(bandai1_dir):
    return read_bvh(bandai1_dir / "data" / "dataset-1_walk_happy_002.bvh")


def untrained(seed: int = 0, architecture: str | None = None) -> EmotionClassifier:
    config = ClassifierConfig(seed=seed)
    if architecture is not None:
        config = replace(config, architecture=architecture)
    torch.manual_seed(seed)
    return EmotionClassifier(config, build_net(config).eval(),
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


def test_architectures_registry():
    assert ARCHITECTURES == {"tcn": EmotionClassifierNet, "stgcn": EmotionGraphNet}
    for name, net in ARCHITECTURES.items():
        assert isinstance(build_net(ClassifierConfig(architecture=name)), net)
    with pytest.raises(ClassifierError, match="unknown classifier architecture 'gru'"):
        ClassifierConfig(architecture="gru")


def test_role_adjacency_is_the_skeleton():
    a = role_adjacency()
    j = len(ROLES)
    assert a.shape == (j, j) and a.dtype == np.float32
    np.testing.assert_array_equal(a, a.T)
    assert (np.diag(a) > 0).all()
    edges = {frozenset((ROLES[u], ROLES[v])) for u, v in zip(*np.nonzero(a), strict=True)
             if u != v}
    assert edges == {frozenset(e) for e in ROLE_EDGES}
    # A tree over all roles: the arms hang from the chest, the legs from the root.
    assert len(edges) == j - 1
    for edge in (("chest", "l_shoulder"), ("chest", "r_shoulder"), ("root", "l_hip"),
                 ("root", "r_hip"), ("neck", "head"), ("l_ankle", "l_toe"),
                 ("r_wrist", "r_handtip")):
        assert frozenset(edge) in edges
    reach = np.linalg.matrix_power(a > 0, j).astype(bool)
    assert reach.all()
    # D^-1/2 (A + I) D^-1/2: each entry is 1 / sqrt(deg u * deg v), and sqrt(deg) is the
    # eigenvector of the largest eigenvalue, 1.
    degree = (a > 0).sum(1)
    np.testing.assert_allclose(a[a > 0], (1 / np.sqrt(np.outer(degree, degree)))[a > 0],
                               rtol=1e-6)
    np.testing.assert_allclose(a @ np.sqrt(degree), np.sqrt(degree), rtol=1e-6)
    np.testing.assert_allclose(np.linalg.eigvalsh(a).max(), 1.0, rtol=1e-6)


def test_joint_nodes_and_graph_block_follow_the_skeleton():
    rng = np.random.default_rng(2)
    x = torch.from_numpy(rng.normal(size=(2, 7, NUM_FEATURES)).astype(np.float32))
    nodes = joint_nodes(x)
    assert nodes.shape == (2, 7, len(ROLES), 6)
    for k in (0, ROLES.index("head"), len(ROLES) - 1):
        np.testing.assert_array_equal(nodes[..., k, :3], x[..., 3 * k:3 * k + 3])
        v = JOINT_COLUMNS // 2 + 3 * k
        np.testing.assert_array_equal(nodes[..., k, 3:], x[..., v:v + 3])
    # One block: a change at the head reaches only the head and its neighbour, the neck.
    torch.manual_seed(0)
    block = _GraphBlock(6, 8, 1).eval()
    moved = nodes.clone()
    moved[..., ROLES.index("head"), :] += 1.0
    with torch.no_grad():
        changed = (block(moved) - block(nodes)).abs().amax((0, 1, 3)) > 0
    assert {ROLES[k] for k in np.flatnonzero(changed.numpy())} == {"head", "neck"}


@pytest.mark.parametrize("architecture", sorted(ARCHITECTURES))
def test_any_window_length_gives_probabilities(architecture):
    model = untrained(architecture=architecture)
    rng = np.random.default_rng(0)
    for length in (30, 31, 45, 150):
        prob = model.predict_features(rng.normal(size=(3, length, NUM_FEATURES)))
        assert prob.shape == (3, 4)
        np.testing.assert_allclose(prob.sum(-1), 1.0, rtol=1e-5)
    assert model.predict_features(rng.normal(size=(30, NUM_FEATURES))).shape == (4,)


@pytest.mark.parametrize("architecture", sorted(ARCHITECTURES))
def test_save_load_round_trip(tmp_path, architecture):
    model = untrained(seed=3, architecture=architecture)
    model.metrics = {"test": {"window_accuracy": 0.5}}
    path = model.save(tmp_path / "c.pt")
    back = EmotionClassifier.load(path)
    assert back.config == model.config and back.metrics == model.metrics
    assert type(back.net) is ARCHITECTURES[architecture]
    x = np.random.default_rng(1).normal(size=(2, 40, NUM_FEATURES))
    np.testing.assert_array_equal(back.predict_features(x), model.predict_features(x))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.pt"]


def test_files_from_before_the_architecture_choice_load_as_tcn(tmp_path):
    model = untrained(seed=4, architecture="tcn")
    payload = torch.load(model.save(tmp_path / "c.pt"), weights_only=True)
    # The config as files held it before the graph network existed.
    for key in ("architecture", "graph_channels", "graph_blocks", "affect_channels"):
        del payload["config"][key]
    torch.save(payload, tmp_path / "old.pt")
    assert ClassifierConfig.from_dict(payload["config"]).architecture == "tcn"
    old = EmotionClassifier.load(tmp_path / "old.pt")
    assert old.config == model.config and type(old.net) is EmotionClassifierNet
    x = np.random.default_rng(5).normal(size=(2, 35, NUM_FEATURES))
    np.testing.assert_array_equal(old.predict_features(x), model.predict_features(x))


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
    # Every architecture was cross-validated on the same folds and seeds; the card tabulates
    # the means, and the default is the one with the higher mean window accuracy.
    compared = model.metrics["architectures"]
    assert set(compared) == set(ARCHITECTURES)
    assert compared[model.config.architecture]["runs"][0] == model.metrics["cross_validation"]
    assert len({(r["windows"], r["folds"]) for c in compared.values() for r in c["runs"]}) == 1
    assert len({tuple(c["seeds"]) for c in compared.values()}) == 1
    assert model.config.architecture == ClassifierConfig().architecture
    assert model.config.architecture == max(compared, key=lambda k: compared[k]["window_accuracy"])
    for name, result in compared.items():
        assert result["window_accuracy"] == pytest.approx(
            np.mean([r["window_accuracy"] for r in result["runs"]]))
        mark = " (this model)" if name == model.config.architecture else ""
        assert f"| {name}{mark} | {result['window_accuracy']:.3f} (" in card


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
