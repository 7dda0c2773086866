"""The committed FCRBM checkpoint (``src/emotive/assets/fcrbm/fcrbm.pt``) and its recipe."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_fcrbm_pipeline import invoke_fcrbm

from emotive.io.bvh import read_bvh
from emotive.models.fcrbm.generate import (
    constant_context,
    default_checkpoint_path,
    emotion_context,
    generate_motion,
    load_fcrbm_model,
)
from emotive.models.fcrbm.training import (
    EXPORTED_KEYS,
    load_fcrbm_checkpoint,
    load_fcrbm_settings,
)

REPO = Path(__file__).resolve().parents[3]


def test_the_committed_checkpoint_is_the_configs_recipe_exported():
    config, settings = load_fcrbm_settings(REPO / "configs" / "fcrbm.toml")
    path = default_checkpoint_path()
    _, codec, ckpt = load_fcrbm_checkpoint(path)
    assert set(ckpt) == set(EXPORTED_KEYS)
    assert ckpt["config"] == {**config.to_dict(), "visible": codec.dim}
    assert ckpt["train"] == settings.to_dict()
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
