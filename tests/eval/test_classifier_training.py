"""The classifier's training pipeline on a few real clips: targets, calibration, unsure, config."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from emotive.data.circumplex import VALENCE_AROUSAL
from emotive.errors import ConfigError
from emotive.eval.classifier import ClassifierConfig, EmotionClassifier
from emotive.eval.classifier_training import (
    WindowSampler,
    load_tracks,
    measure,
    read_config,
    split_features,
    train_classifier,
)

REPO = Path(__file__).resolve().parents[2]
STYLES = ("happy", "sad", "angry", "normal", "tired", "proud")


@pytest.fixture(scope="module")
def tracks(bandai1_dir):
    every = load_tracks(("bandai-namco-1",))
    # Walks and runs of a few styles: every split keeps some of each.
    return [t for t in every if t.style in STYLES and t.content in ("walk", "run", "walk-left")]


@pytest.fixture(scope="module")
def quick():
    return replace(ClassifierConfig(datasets=("bandai-namco-1",)), augment_copies=1, epochs=2,
                   steps_per_epoch=3, batch_size=16)


@pytest.fixture(scope="module")
def data(tracks, quick):
    return split_features(tracks, quick)


@pytest.mark.data
def test_targets_and_augmented_variants(tracks, quick, data):
    assert {t.split for t in tracks} == {"train", "val", "test"}
    assert all(t.points.shape[1:] == (21, 3) and t.fps == 30.0 for t in tracks)
    train = data["train"]
    n_train = sum(t.split == "train" for t in tracks)
    assert len(train) == 2 * n_train and sorted({i.variant for i in train}) == [0, 1]
    assert all(i.variant == 0 for s in ("val", "test") for i in data[s])
    by = {(i.style, i.variant): i for i in train}
    assert by[("normal", 0)].label == quick.labels.index("neutral")
    assert by[("proud", 0)].label == -1 and by[("proud", 0)].style_index == -1
    assert by[("tired", 0)].style_index == quick.style_labels.index("exhausted")
    np.testing.assert_allclose(by[("sad", 0)].valence_arousal,
                               [VALENCE_AROUSAL["sad"].valence, VALENCE_AROUSAL["sad"].arousal])
    # The variant is the same clip on another rig and frame rate: other features, same length
    # in time.
    a, b = by[("happy", 0)], by[("happy", 1)]
    assert abs(len(a.features) - len(b.features)) <= 1
    assert not np.allclose(a.features[:len(b.features)], b.features[:len(a.features)])


@pytest.mark.data
def test_quick_training_calibrates_and_sets_the_unsure_distance(quick, data, tmp_path):
    model = train_classifier(quick, data=data)
    assert 0.05 <= model.temperature <= 20.0 and np.isfinite(model.unsure_distance)
    for split in ("val", "test"):
        result = model.metrics[split]
        assert result["clips"] == sum(i.label >= 0 for i in data[split])
        assert 0.0 <= result["ece"] <= 1.0 and 0.0 <= result["ece_uncalibrated"] <= 1.0
        assert 0.0 <= result["unsure_rate"] <= 1.0
    assert set(model.metrics["test_by_dataset"]) == {"bandai-namco-1"}
    # About 1 % of fresh training windows lie beyond the 99th-percentile distance.
    sampler = WindowSampler(data["train"], quick)
    rng = np.random.default_rng(5)
    unsure = [model.outputs(sampler.draw(rng, 16)[0])["unsure"] for _ in range(150)]
    assert 0.0 < np.concatenate(unsure).mean() < 0.05
    back = EmotionClassifier.load(model.save(tmp_path / "c.pt"))
    assert back.temperature == model.temperature
    assert measure(back, data["test"]) == model.metrics["test"]


@pytest.mark.data
def test_the_sampler_balances_styles_and_labels(quick, data):
    sampler = WindowSampler(data["train"], quick)
    # 0.8 to 4 s at 15 fps.
    assert list(sampler.lengths) == [12, 24, 36, 48, 60]
    rng = np.random.default_rng(0)
    draws = [sampler.draw(rng, 100) for _ in range(40)]
    assert {x.shape[1] for x, *_ in draws} == set(sampler.lengths)
    style, va = (np.concatenate([d[k] for d in draws]) for k in (2, 3))
    # Tired is the only shared style here besides normal (as exhausted and neutral).
    assert set(style.tolist()) == {-1, quick.style_labels.index("neutral"),
                                   quick.style_labels.index("exhausted")}
    assert {(round(float(v[0]), 3), round(float(v[1]), 3)) for v in va} == {
        (round(VALENCE_AROUSAL[s].valence, 3), round(VALENCE_AROUSAL[s].arousal, 3))
        for s in ("happy", "sad", "angry", "neutral", "tired", "proud")}
    # In the shortest windows, which every clip can fill, happy, sad, angry and neutral each
    # come from one style group of six (longer windows skip the shorter clips).
    draws += [sampler.draw(rng, 100) for _ in range(200)]
    short = np.concatenate([d[1] for d in draws if d[0].shape[1] == sampler.lengths[0]])
    counts = np.bincount(short[short >= 0], minlength=4)
    assert len(short) >= 2000 and np.all(np.abs(counts / len(short) - 1 / 6) < 0.04)
    assert np.all(sampler.label_weight > 0)


def test_the_config_file_is_the_default_config(tmp_path):
    assert read_config(REPO / "configs" / "classifier.toml") == ClassifierConfig()
    bad = tmp_path / "bad.toml"
    bad.write_text("chanels = 3\n")
    with pytest.raises(ConfigError, match=r"bad.toml: .*chanels.*configs/classifier.toml"):
        read_config(bad)
    bad.write_text("channels = [\n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        read_config(bad)
    with pytest.raises(ConfigError, match="cannot be read"):
        read_config(tmp_path / "none.toml")
