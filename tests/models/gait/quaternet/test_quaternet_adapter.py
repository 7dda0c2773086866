"""The QuaterNet baseline through the registry: the Table 1 predictor of its checkpoint."""

from __future__ import annotations

import pytest

from emotive.errors import ConfigError
from emotive.models.api import Predictor
from emotive.models.gait.quaternet.adapter import default_checkpoint_path
from emotive.models.registry import get_model


def test_the_committed_checkpoint_is_a_predictor():
    predictor = get_model("quaternet").load("predictor")
    assert isinstance(predictor, Predictor) and predictor.name == "QuaterNet"
    assert default_checkpoint_path().is_file()


def test_another_checkpoint_file_is_loaded_or_named(tmp_path):
    with pytest.raises(ConfigError):
        get_model("quaternet").load("predictor", weights=tmp_path / "none.pt")
