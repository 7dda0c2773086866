"""The checks of :mod:`emotive.models.checkpoint_checks`, and a resume that changes the seed.

The damaged copies of the shipped checkpoints are in ``test_checkpoint_corruption.py``; here
each check alone: config fields by type and range (hypothesis over numbers), entries and their
size, weights built on the meta device, the model cards' fingerprints, and ``--resume`` with
another ``--seed`` refused with both seeds named.
"""

from __future__ import annotations

import math
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from emotive.errors import ConfigError
from emotive.models import checkpoint_checks
from emotive.models.checkpoint_checks import (
    Range,
    build_weights,
    card_fingerprints,
    check_archive,
    check_entries,
    check_fields,
    check_fingerprint,
    sha256_of,
)
from emotive.models.fcrbm.config import FCRBMConfig
from emotive.models.fcrbm.data import FrameCodec
from emotive.models.fcrbm.generate import default_checkpoint_path as fcrbm_checkpoint_path
from emotive.models.fcrbm.training import FCRBMData, FCRBMTrainSettings, train_fcrbm
from emotive.models.gait.model import load_gait_model
from emotive.models.training import check_resumable


@dataclass(frozen=True)
class Toy:
    """A config of every annotation :func:`check_fields` knows."""

    rate: float = 30.0
    size: int = 4
    name: str = "toy"
    on: bool = True
    rates: tuple[float, ...] = (1.0, 2.0)
    limit: float | None = None


RANGES = {"rate": Range(0, 100, above=True), "size": Range(1, 8), "rates": Range(0, 10)}


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_a_float_field_passes_exactly_when_finite_and_in_range(value):
    expected = math.isfinite(value) and 0 < value <= 100
    try:
        check_fields(Toy(rate=value), RANGES)
    except ValueError as exc:
        assert not expected, exc
        assert str(exc).startswith("Toy.rate must be")
    else:
        assert expected


@given(st.integers(-(2**70), 2**70))
def test_an_int_field_passes_exactly_when_in_range(value):
    try:
        check_fields(Toy(size=value), RANGES)
    except ValueError as exc:
        assert not 1 <= value <= 8 and "Toy.size must be in [1, 8]" in str(exc)
    else:
        assert 1 <= value <= 8


@pytest.mark.parametrize(("values", "words"), [
    ({"size": 2.0}, "Toy.size must be an integer, got 2.0"),
    ({"size": True}, "Toy.size must be an integer, got True"),
    ({"rate": "30"}, "Toy.rate must be a number, got '30'"),
    ({"rate": False}, "Toy.rate must be a number"),
    ({"name": 3}, "Toy.name must be a text"),
    ({"on": 1}, "Toy.on must be true or false"),
    ({"rates": (1.0, math.nan)}, "Toy.rates item 1 (nan) must be a finite number"),
    ({"rates": 1.0}, "Toy.rates must be a list"),
    ({"rates": (1.0, 11.0)}, "Toy.rates must be in [0, 10]"),
    ({"limit": math.inf}, "Toy.limit must be a finite number"),
    ({"name": "x" * 500}, None),
])
def test_wrong_types_are_named_with_the_field(values, words):
    if words is None:
        check_fields(Toy(**values), RANGES)
        return
    with pytest.raises(ValueError) as info:
        check_fields(Toy(**values), RANGES)
    assert str(info.value).startswith(words), info.value
    assert len(str(info.value)) < 120


def test_integers_of_numpy_and_none_where_allowed_pass():
    check_fields(Toy(size=np.int64(3), rate=np.float32(2.5), limit=None), RANGES)
    assert str(Range(0, 1, above=True)) == "(0, 1]" and str(Range(1, 8)) == "[1, 8]"


def test_a_nan_frame_rate_is_refused_by_every_config_even_from_toml():
    from emotive.eval.classifier import ClassifierConfig, ClassifierError
    from emotive.models.gait.config import GaitConfig
    from emotive.models.gait.quaternet.config import QuaterNetConfig

    for make in (GaitConfig, QuaterNetConfig):
        with pytest.raises(ValueError, match="fps must be"):
            make(fps=math.nan)
    with pytest.raises(ClassifierError, match=r"ClassifierConfig\.fps must be a finite number"):
        ClassifierConfig(fps=math.nan)
    with pytest.raises(ValueError, match=r"FCRBMConfig\.gibbs must be in"):
        FCRBMConfig(visible=3, gibbs=10**9)


def test_entries_must_be_those_of_the_kind_and_extras_small():
    state = {"w": torch.zeros(1000)}
    check_entries({"state": state, "rng": torch.zeros(3000)}, ("state", "rng"))
    with pytest.raises(ValueError, match=r"unexpected entry 'blob' \(a torch.float32 tensor of "
                                         r"4 MB\)"):
        check_entries({"state": state, "blob": torch.zeros(1_000_000)}, ("state",))
    with pytest.raises(ValueError, match=r"4\.01 MB of tensors besides its 4 kB of weights"):
        check_entries({"state": state, "rng": {"x": torch.zeros(1_002_000)}}, ("state", "rng"))


def test_weights_are_checked_on_the_meta_device_before_any_memory():
    def huge() -> torch.nn.Module:  # 4 TB of float32 if it were built for real
        return torch.nn.Linear(1_000_000, 1_000_000)

    with pytest.raises(ValueError, match="state lacks 'weight'"):
        build_weights(huge, {})
    small = torch.nn.Linear(3, 2)
    built = build_weights(lambda: torch.nn.Linear(3, 2), small.state_dict())
    assert torch.equal(built.weight, small.weight)
    with pytest.raises(ValueError, match=r"state\['weight'\] holds 5, beyond the trained range "
                                         r"\(at most 1\)"):
        build_weights(lambda: torch.nn.Linear(3, 2),
                      {"weight": torch.full((2, 3), 5.0), "bias": torch.zeros(2)}, limit=1.0)


def test_every_shipped_weight_file_matches_the_fingerprint_of_its_card():
    files = sorted(checkpoint_checks.assets_folder().glob("*/*.pt"))
    assert len(files) >= 7
    for path in files:
        assert card_fingerprints(path.parent / "MODEL_CARD.md").get(path.name) == sha256_of(path)


def test_a_shipped_file_without_its_fingerprint_line_is_refused(tmp_path, monkeypatch):
    root = tmp_path / "assets"
    shutil.copytree(checkpoint_checks.assets_folder() / "gait", root / "gait")
    monkeypatch.setattr(checkpoint_checks, "assets_folder", lambda: root)
    card = root / "gait" / "MODEL_CARD.md"
    card.write_text("\n".join(line for line in card.read_text().splitlines()
                              if "`emotive-gait.pt`: `" not in line))
    with pytest.raises(ConfigError, match="without a fingerprint") as info:
        load_gait_model(root / "gait" / "emotive-gait.pt")
    assert "\n" not in str(info.value)
    # Outside the assets folder a file is a user's: no card, no fingerprint check.
    user = tmp_path / "mine.pt"
    shutil.copy(root / "gait" / "emotive-gait.pt", user)
    check_fingerprint(user)
    assert load_gait_model(user) is not None


def test_a_flipped_bit_in_a_weight_record_fails_its_crc(tmp_path):
    path = tmp_path / "net.pt"
    torch.save({"state": torch.nn.Linear(40, 40).state_dict()}, path)
    check_archive(path)
    data = bytearray(path.read_bytes())
    at = data.find(np.float32(torch.load(path)["state"]["weight"][3, 5]).tobytes())
    data[at] ^= 0x01  # the lowest mantissa bit: a plausible weight, unseen by value checks
    path.write_bytes(bytes(data))
    with pytest.raises(ValueError, match=r"record '.*/data/0' fails its CRC-32 check"):
        check_archive(path)
    # A file that is not a zip archive is left to torch.load's own verdict.
    text = tmp_path / "text.pt"
    text.write_text("not an archive")
    check_archive(text)


def test_check_resumable_refuses_another_seed_naming_both():
    saved = {"config": {"size": 3}, "train": {"epochs": 2}, "seed": 3}
    check_resumable(Path("last.pt"), saved, {"size": 3}, {"epochs": 4}, 3)
    with pytest.raises(ConfigError) as info:
        check_resumable(Path("last.pt"), saved, {"size": 3}, {"epochs": 4}, 5)
    assert str(info.value) == ("last.pt: made with --seed 3, resumed with --seed 5; cannot resume "
                               "(resume with --seed 3, or give a new --out to start over with "
                               "--seed 5)")
    # Checkpoints written before the seed was saved resume as before.
    check_resumable(Path("last.pt"), {k: v for k, v in saved.items() if k != "seed"},
                    {"size": 3}, {"epochs": 4}, 5)


def test_resuming_an_fcrbm_training_with_another_seed_is_refused(tmp_path):
    codec = FrameCodec.from_dict(torch.load(fcrbm_checkpoint_path(), weights_only=True)["codec"])
    rng = np.random.default_rng(0)

    def clip(name: str, arousal: float) -> tuple[str, np.ndarray, np.ndarray]:
        return name, rng.normal(size=(40, codec.dim)), np.tile([2.0, arousal], (40, 1))

    data = FCRBMData(codec, {"train": [clip("a", 1.0), clip("b", 3.0)], "val": [clip("c", 2.0)]})
    config = FCRBMConfig(visible=codec.dim, order=2, hidden=8, factors=4,
                         factors_past_visible=4, factors_past_hidden=4, gibbs=2)
    settings = FCRBMTrainSettings(epochs=1, batch_size=32)
    train_fcrbm(config, settings, progress=False, out_dir=tmp_path, seed=4, data=data)
    with pytest.raises(ConfigError, match=r"made with --seed 4, resumed with --seed 0; cannot "
                                          r"resume \(resume with --seed 4"):
        train_fcrbm(config, FCRBMTrainSettings(epochs=2, batch_size=32), progress=False,
                    out_dir=tmp_path, resume=True, data=data)
    more = train_fcrbm(config, FCRBMTrainSettings(epochs=2, batch_size=32), progress=False,
                       out_dir=tmp_path, resume=True, seed=4, data=data)
    assert [row["epoch"] for row in more.history] == [1, 2]
