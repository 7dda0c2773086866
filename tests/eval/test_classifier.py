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
    FILE_FORMAT,
    ClassifierConfig,
    ClassifierError,
    EmotionClassifier,
    default_classifier_path,
    frame_features,
    load_default_classifier,
)
from emotive.eval.classifier_nets import (
    ARCHITECTURES,
    JOINT_COLUMNS,
    NUM_FEATURES,
    ROLE_EDGES,
    EmotionClassifierNet,
    EmotionGraphNet,
    _GraphBlock,
    build_net,
    joint_nodes,
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
    width = model.net.out.in_features
    rng = np.random.default_rng(1)
    model.temperature = 1.7
    model.embedding_mean = rng.normal(size=width)
    model.embedding_precision = np.eye(width) * 2.0
    model.unsure_distance = 3.5
    path = model.save(tmp_path / "c.pt")
    back = EmotionClassifier.load(path)
    assert back.config == model.config and back.metrics == model.metrics
    assert type(back.net) is ARCHITECTURES[architecture]
    assert (back.temperature, back.unsure_distance) == (1.7, 3.5)
    np.testing.assert_array_equal(back.embedding_precision, model.embedding_precision)
    x = rng.normal(size=(2, 40, NUM_FEATURES))
    np.testing.assert_array_equal(back.predict_features(x), model.predict_features(x))
    for key in ("distance", "unsure", "valence_arousal"):
        np.testing.assert_array_equal(back.outputs(x)[key], model.outputs(x)[key])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.pt"]


def test_temperature_changes_confidence_not_the_ranking():
    model = untrained(seed=2)
    x = np.random.default_rng(3).normal(size=(6, 20, NUM_FEATURES))
    sharp = model.predict_features(x)
    model.temperature = 4.0
    soft = model.predict_features(x)
    np.testing.assert_array_equal(sharp.argmax(-1), soft.argmax(-1))
    assert (soft.max(-1) < sharp.max(-1)).all()


def test_files_of_format_1_are_refused_with_the_fix(tmp_path):
    model = untrained(seed=4)
    payload = torch.load(model.save(tmp_path / "c.pt"), weights_only=True)
    payload["format"] = "emotive-emotion-classifier/1"
    torch.save(payload, tmp_path / "old.pt")
    with pytest.raises(ClassifierError, match=r"must be retrained.*emotive train classifier"):
        EmotionClassifier.load(tmp_path / "old.pt")
    payload["format"] = FILE_FORMAT
    payload["temperature"] = torch.tensor(-1.0, dtype=torch.float64)
    torch.save(payload, tmp_path / "bad.pt")
    with pytest.raises(ClassifierError, match=r"'temperature' is -1\.0"):
        EmotionClassifier.load(tmp_path / "bad.pt")


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
    # One stride (0.8 s, 12 feature frames) is enough: windows of 0.8 s, or a 0.8 s clip.
    times, prob = model.classify(walk, window_seconds=0.8, hop_seconds=0.8)
    assert len(times) == 5 and np.allclose(times[0], 0.4)
    stride = walk.replace(rotations=walk.rotations[:24], positions=walk.positions[:24])
    assert model.classify(stride)[1].shape == (1, 4)
    with pytest.raises(ClassifierError, match=r"window of 0.5 s is too short for .* \(4.50 s\)"
                                              r".* at least 0.8 s"):
        model.classify(walk, window_seconds=0.5)
    short = walk.replace(rotations=walk.rotations[:20], positions=walk.positions[:20])
    with pytest.raises(ClassifierError, match=r"lasts 0.6\d s; the classifier needs at least "
                                              r"0.8 s"):
        model.classify(short)


def test_committed_classifier_and_card():
    model = load_default_classifier()
    assert model.labels == ("happy", "sad", "angry", "neutral")
    assert model.config == ClassifierConfig()
    assert model.config.datasets == ("bandai-namco-1", "bandai-namco-2-locomotion")
    assert model.config.min_seconds == 0.8
    assert 0 < model.temperature and np.isfinite(model.unsure_distance)
    for result in (model.metrics["test"], model.metrics["val"],
                   *model.metrics["test_by_dataset"].values()):
        assert 0.0 <= result["window_accuracy"] <= 1.0
        assert np.array(result["confusion"]).sum() == result["windows"]
    card = (default_classifier_path().parent / "MODEL_CARD.md").read_text()
    assert "CC BY-NC 4.0" in card
    for name, result in model.metrics["test_by_dataset"].items():
        assert f"### Test clips of {name}" in card
        assert f"window accuracy: {result['window_accuracy']:.3f}" in card
        assert f"{result['ece_uncalibrated']:.3f} before temperature scaling" in card
    for entry in model.metrics["leave_one_studio_out"].values():
        assert f"| {entry['trained_on']} | {entry['tested_on']} | " \
               f"{entry['result']['style_accuracy']:.3f}" in card
    unsure = model.metrics["unsure"]
    assert f"| held-out clips, 4 s windows | {unsure['held_out']['4s']:.3f} |" in card
    assert f"| random joint noise | {unsure['joint_noise']:.3f} |" in card
    assert f"T = {model.temperature:.3f}" in card
    # The weights stay small enough to commit.
    assert default_classifier_path().stat().st_size < 1_000_000


def test_a_trained_card_carries_the_fingerprint_its_shipped_copy_is_checked_against(tmp_path):
    from emotive.eval.classifier_card import classifier_card
    from emotive.models.checkpoint_checks import card_fingerprints, check_fingerprint, sha256_of

    shipped = default_classifier_path()
    weights = (shipped.name, sha256_of(shipped))
    card = tmp_path / "MODEL_CARD.md"
    card.write_text(classifier_card(load_default_classifier(), {"train": [], "val": [],
                                                                "test": []}, weights))
    assert card_fingerprints(card) == {shipped.name: weights[1]}
    assert card_fingerprints(shipped.parent / "MODEL_CARD.md") == {shipped.name: weights[1]}
    check_fingerprint(shipped)


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
