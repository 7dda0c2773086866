"""Fixtures of the gait network tests: the small rig and a narrow config."""

from __future__ import annotations

import pytest
from gait_helpers import NUM_JOINTS, make_skeleton

from emotive.core import Skeleton
from emotive.models.gait import GaitConfig, GaitRig


@pytest.fixture(scope="module")
def skeleton() -> Skeleton:
    return make_skeleton()


@pytest.fixture(scope="module")
def rig(skeleton: Skeleton) -> GaitRig:
    return GaitRig.from_skeleton(skeleton)


@pytest.fixture
def small_config() -> GaitConfig:
    """Narrow layers over the 19-joint rig, for fast tests."""
    return GaitConfig(
        num_joints=NUM_JOINTS, enc1_hidden=16, enc1_out=8, enc2_hidden=16, enc2_out=8,
        gru_hidden=24, gru_layers=2, root_hidden=8, versor_hidden=24,
    )
