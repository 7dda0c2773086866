"""Tests of GaitConfig: defaults, validation and the JSON round trip of checkpoints."""

from __future__ import annotations

import json

import pytest

from emotive.data.emotion import ALL_LABELS, DEFAULT_LABELS
from emotive.errors import EmotionError
from emotive.models.gait import GaitConfig, GaitNetwork


def test_defaults_follow_the_paper_where_it_gives_values():
    cfg = GaitConfig()
    assert cfg.labels == DEFAULT_LABELS and cfg.num_labels == 4
    assert (cfg.motion_weight, cfg.pose_weight, cfg.affective_weight, cfg.root_weight,
            cfg.foot_contact_weight) == (1.0, 1.0, 1.0, 1.0, 1.0)
    assert cfg.use_affective and cfg.use_root_loss
    assert cfg.gru_hidden <= 256 and cfg.num_joints == 22 and cfg.fps == 30.0


def test_json_round_trip_keeps_every_field():
    cfg = GaitConfig(
        labels=ALL_LABELS, num_joints=19, fps=15, gru_hidden=64, gru_layers=2, head_hidden=8,
        affective_weight=0.5, versor_weight=0.1, use_affective=False, use_root_loss=False,
    )
    text = json.dumps(cfg.to_dict())
    back = GaitConfig.from_dict(json.loads(text))
    assert back == cfg
    assert isinstance(back.labels, tuple) and back.fps == 15.0
    assert GaitConfig.from_json(cfg.to_json()) == cfg


def test_saved_config_rebuilds_the_same_network():
    cfg = GaitConfig(num_joints=5, gru_hidden=16, versor_hidden=16)
    net = GaitNetwork(GaitConfig.from_json(cfg.to_json()))
    assert net.num_parameters == GaitNetwork(cfg).num_parameters


def test_unknown_key_is_rejected():
    with pytest.raises(ValueError, match="unknown GaitConfig fields"):
        GaitConfig.from_dict({**GaitConfig().to_dict(), "dropout": 0.1})


@pytest.mark.parametrize("changes", [
    {"gru_hidden": 0}, {"num_joints": -1}, {"enc1_out": 2.5}, {"head_hidden": -1},
    {"fps": 0}, {"pose_weight": -1.0}, {"use_affective": "yes"},
])
def test_bad_values_are_rejected(changes):
    with pytest.raises(ValueError, match="GaitConfig"):
        GaitConfig(**changes)


def test_unknown_label_is_rejected():
    with pytest.raises(EmotionError):
        GaitConfig(labels=("happy", "joyful"))
