"""The committed FCRBM checkpoint (``src/emotive/assets/fcrbm/fcrbm.pt``) and its recipe."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_fcrbm_pipeline import invoke_fcrbm

from emotive.io.bvh import read_bvh
from emotive.models.fcrbm.checkpoint import EXPORTED_KEYS, load_fcrbm_checkpoint
from emotive.models.fcrbm.config import FCRBMConfig
from emotive.models.fcrbm.generate import (
    constant_context,
    default_checkpoint_path,
    emotion_context,
    generate_motion,
    load_fcrbm_model,
)
from emotive.models.fcrbm.training import FCRBMTrainSettings, load_fcrbm_settings

REPO = Path(__file__).resolve().parents[3]


def test_the_committed_checkpoint_is_the_configs_recipe_exported():
    config, settings = load_fcrbm_settings(REPO / "configs" / "fcrbm.toml")
    path = default_checkpoint_path()
    _, codec, ckpt = load_fcrbm_checkpoint(path)
    assert set(ckpt) == set(EXPORTED_KEYS)
    saved = FCRBMConfig.from_dict(ckpt["config"]).to_dict()  # keys added since: defaults
    assert saved == {**config.to_dict(), "visible": codec.dim}
    assert FCRBMTrainSettings(**ckpt["train"]).to_dict() == settings.to_dict()
    assert ckpt["epoch"] == settings.epochs
    assert path.stat().st_size < 8e6
    assert (path.parent / "MODEL_CARD.md").is_file()


def test_the_default_model_generates_from_the_cli(tmp_path):
    out = tmp_path / "happy.bvh"
    result = invoke_fcrbm("generate", "--emotion", "happy", "--seconds", 1, "--out", out)
    assert result.exit_code == 0, result.output
    motion = read_bvh(out)
    model = load_fcrbm_model()
    assert motion.num_frames == 30 and np.isfinite(motion.positions).all()
    assert motion.skeleton.names == model.codec.skeleton.names


def test_the_default_model_walks_at_the_neutral_point():
    """The committed model's walk from the mean frame at (2, 2): the feet move and the root
    travels (2 s, one torch thread; the README's walking screen measures it in full)."""
    model = load_fcrbm_model()
    motion, _ = generate_motion(model, constant_context(*emotion_context("neutral"), 60))
    p = motion.positions_with_end_sites()
    hips = motion.skeleton.names.index("Hips")
    assert np.linalg.norm(p[-1, hips, [0, 2]] - p[0, hips, [0, 2]]) > 0.5
    feet = [motion.skeleton.names.index(n) for n in ("Foot_L", "Foot_R")]
    relative = p[:, feet] - p[:, hips, None]
    assert np.ptp(relative[..., 2], axis=0).min() > 0.1


@pytest.mark.data
def test_the_committed_codec_is_fitted_on_the_configs_data(bandai1_dir, bandai2_dir):
    from emotive.models.fcrbm.training import load_fcrbm_data

    _, settings = load_fcrbm_settings(REPO / "configs" / "fcrbm.toml")
    data = load_fcrbm_data(settings)
    _, codec, _ = load_fcrbm_checkpoint(default_checkpoint_path())
    ours, theirs = codec.to_dict(), data.codec.to_dict()
    assert ours["keep"] == theirs["keep"]
    np.testing.assert_allclose(ours["mean"], theirs["mean"], atol=1e-6)
    np.testing.assert_allclose(ours["std"], theirs["std"], rtol=1e-5)


def test_the_default_model_is_read_as_the_emotion_it_is_asked_for():
    """Happy, sad and angry from the mean frame (10 s, seeds 0 and 1): the evaluation suite's
    classifier reads at least 70 % of the windows as asked, the last window of every run
    right, and angry moves its joints faster than sad (the README's evaluation measures every
    emotion over 20 s and 3 seeds)."""
    from emotive.eval.classifier import load_default_classifier, window_labels

    model = load_fcrbm_model()
    classifier = load_default_classifier()
    speed = {}
    for emotion in ("happy", "sad", "angry"):
        read, speeds = [], []
        for seed in (0, 1):
            motion, _ = generate_motion(model, constant_context(*emotion_context(emotion), 300),
                                        seed=seed)
            labels = window_labels(classifier.classify(motion)[1], classifier.labels)
            assert labels and labels[-1] == emotion, (emotion, seed, labels)
            read += labels
            p = motion.positions_with_end_sites()
            relative = p - p[:, :1]
            speeds.append(np.linalg.norm(np.diff(relative, axis=0), axis=-1).mean() * model.fps)
        assert np.mean([label == emotion for label in read]) >= 0.7, (emotion, read)
        speed[emotion] = np.mean(speeds)
    assert speed["angry"] > 1.5 * speed["sad"], speed
