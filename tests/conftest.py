"""Shared test helpers: real-data location and synthetic fixtures."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from emotive.core import Motion, Skeleton
from emotive.errors import DataError
from emotive.transforms.np_rotations import euler_to_quaternion

REPO = Path(__file__).resolve().parents[1]


def require_data_or_skip(reason: str) -> None:
    """Skip a data test, or fail when CI demands the data (``EMOTIVE_REQUIRE_DATA=1``)."""
    if os.environ.get("EMOTIVE_REQUIRE_DATA") == "1":
        pytest.fail(f"EMOTIVE_REQUIRE_DATA=1 but the data is missing: {reason}")
    pytest.skip(reason)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(0)


def make_random_motion(
    rng: np.random.Generator, frames: int = 20, orders: tuple[str, ...] = ("ZXY", "XYZ", "YZX")
) -> Motion:
    """A 5-joint rig (two joints with position channels, two end sites) in random poses."""
    names = ("Hips", "Spine", "Head", "UpperLeg_L", "LowerLeg_L")
    parents = np.array([-1, 0, 1, 0, 3])
    offsets = np.array([[0, 0.9, 0], [0, 0.1, 0], [0, 0.3, 0], [0.1, -0.05, 0], [0, -0.4, 0]])
    channels = []
    for j in range(len(names)):
        order = orders[j % len(orders)]
        rot = tuple(f"{a}rotation" for a in order)
        channels.append(("Xposition", "Yposition", "Zposition", *rot) if j in (0, 3) else rot)
    sk = Skeleton(names, parents, offsets, tuple(channels), [2, 4], [[0, 0.1, 0], [0, -0.05, 0.1]])
    euler = rng.uniform(-np.pi, np.pi, (frames, len(names), 3))
    euler[..., 1] *= 0.45  # middle angle inside (-90, 90) degrees
    rotations = np.stack([euler_to_quaternion(euler[:, j], "".join(c[0] for c in channels[j][-3:]))
                          for j in range(len(names))], 1)
    positions = np.broadcast_to(offsets, (frames, len(names), 3)).copy()
    positions[:, 0] += rng.normal(0, 1, (frames, 3))
    positions[:, 3] += rng.normal(0, 0.01, (frames, 3))
    return Motion(sk, rotations, positions, 30.0, metadata={"file_unit": "cm"})


@pytest.fixture
def random_motion():
    """Factory of synthetic motions: ``random_motion(frames=20, orders=("ZXY",), seed=0)``."""

    def make(frames: int = 20, orders: tuple[str, ...] = ("ZXY", "XYZ", "YZX"), seed: int = 0):
        return make_random_motion(np.random.default_rng(seed), frames, orders)

    return make


def _dataset(name: str) -> Path:
    from emotive.data import dataset_dir

    try:
        return dataset_dir(name)
    except DataError as exc:
        require_data_or_skip(f"dataset {name} is not available ({exc})")
        raise


@pytest.fixture(scope="session")
def bandai1_dir() -> Path:
    """Extracted Bandai Namco dataset 1 (folder holding ``data/*.bvh``)."""
    return _dataset("bandai-namco-1")


@pytest.fixture(scope="session")
def bandai2_dir() -> Path:
    """Extracted Bandai Namco dataset 2, locomotion part."""
    return _dataset("bandai-namco-2-locomotion")
