"""FCRBMConfig: defaults of the paper, JSON round trip and validation."""

from __future__ import annotations

import json

import pytest

from emotive.models.fcrbm.config import FCRBMConfig


def test_defaults_are_the_papers_model() -> None:
    cfg = FCRBMConfig(visible=52)
    assert (cfg.context, cfg.order, cfg.hidden) == (2, 6, 400)
    assert (cfg.factors, cfg.factors_past_visible, cfg.factors_past_hidden) == (300, 300, 300)


def test_json_round_trip() -> None:
    cfg = FCRBMConfig(
        visible=7, order=3, hidden=11, factors=5, learning_rate=0.02, cd_steps=2, seed=9
    )
    back = FCRBMConfig.from_dict(json.loads(json.dumps(cfg.to_dict())))
    assert back == cfg
    assert back.to_dict() == cfg.to_dict()


def test_from_dict_rejects_unknown_keys() -> None:
    data = FCRBMConfig(visible=3).to_dict() | {"hiden": 4}
    with pytest.raises(ValueError, match="hiden"):
        FCRBMConfig.from_dict(data)


@pytest.mark.parametrize(
    ("field", "value"),
    [("visible", 0), ("order", -1), ("hidden", 2.5), ("cd_steps", 0), ("momentum", 1.0),
     ("learning_rate", 0.0), ("weight_decay", -1e-3), ("visible_autoregression", 1)],
)  # fmt: skip
def test_invalid_values_raise(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=field):
        FCRBMConfig(**{"visible": 3, field: value})


def test_checkpoints_from_before_the_switch_keep_the_papers_model() -> None:
    data = FCRBMConfig(visible=3).to_dict()
    del data["visible_autoregression"]
    assert FCRBMConfig.from_dict(data).visible_autoregression is True
