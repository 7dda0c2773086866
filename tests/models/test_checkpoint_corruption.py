"""A generated corpus of damaged copies of every shipped checkpoint: none is accepted.

Each shipped checkpoint kind (gait network, QuaterNet, FCRBM, classifier) gets damage of every
sort an outside campaign tried (truncation, flipped and appended bytes, tensors of another
dtype, scaled weights, extra and missing tensors, NaN and infinity, config values that are NaN,
infinite, out of range or of the wrong type); every variant must be a one-line
:class:`~emotive.errors.ConfigError` naming the file, and only the pristine copies load. Byte
damage is mostly loaded as a shipped file (from a copy of the assets folder, where the model
card's fingerprint catches it), flipped bits also as a user's copy (the zip archive's CRC-32);
the other damage as a user's checkpoint (the tensor and config checks).
"""

from __future__ import annotations

import math
import shutil
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from emotive.errors import ConfigError
from emotive.eval.classifier import EmotionClassifier, default_classifier_path
from emotive.models import checkpoint_checks
from emotive.models.fcrbm.checkpoint import load_fcrbm_checkpoint
from emotive.models.fcrbm.generate import default_checkpoint_path as fcrbm_checkpoint_path
from emotive.models.gait.config import GaitConfig
from emotive.models.gait.model import default_checkpoint_path as gait_checkpoint_path
from emotive.models.gait.model import load_gait_model
from emotive.models.gait.network import GaitNetwork
from emotive.models.gait.quaternet.adapter import (
    default_checkpoint_path as quaternet_checkpoint_path,
)
from emotive.models.gait.quaternet.config import QuaterNetConfig
from emotive.models.gait.quaternet.network import QuaterNetwork
from emotive.models.gait.quaternet.training import load_quaternet_checkpoint

#: kind: (shipped file, loader).
KINDS: dict[str, tuple[Callable[[], Path], Callable[[Path], Any]]] = {
    "gait": (gait_checkpoint_path, load_gait_model),
    "quaternet": (quaternet_checkpoint_path, load_quaternet_checkpoint),
    "fcrbm": (fcrbm_checkpoint_path, load_fcrbm_checkpoint),
    "classifier": (default_classifier_path, EmotionClassifier.load),
}

#: Bad values given to a config number in turn, so that every field meets several sorts.
BAD_NUMBERS: tuple[Any, ...] = (math.nan, math.inf, 1e12, "text", -1e12, -math.inf, [1.0])
#: Bad values given to an integer field in turn.
BAD_INTEGERS: tuple[Any, ...] = (2.5, 10**12, "text", -5, math.nan, True, None)


@dataclass(frozen=True)
class Variant:
    """One damaged copy.

    Attributes:
        name: what was done, for failure messages.
        damage: the sort of damage, for the count by sort.
        payload: an object to ``torch.save``, or the file's bytes.
        shipped: loaded from the copy of the assets folder (as the shipped default).
    """

    name: str
    damage: str
    payload: Any
    shipped: bool = False


#: Marks an entry :func:`_replace` deletes.
DELETE = object()
#: An entry each kind may hold beside its weights (the training checkpoint's random state or
#: optimizer), where an oversized tensor hides.
SPARE_ENTRY = {"gait": "optimizer", "quaternet": "optimizer", "fcrbm": "rng"}


def _replace(ckpt: dict[str, Any], path: tuple[str, ...], value: Any) -> dict[str, Any]:
    """A copy of ``ckpt`` with the entry at ``path`` (keys into nested dicts) set to ``value``
    (deleted when ``value`` is :data:`DELETE`); only the dicts on the path are copied."""
    out = dict(ckpt)
    if len(path) == 1:
        if value is DELETE:
            del out[path[0]]
        else:
            out[path[0]] = value
        return out
    out[path[0]] = _replace(ckpt[path[0]], path[1:], value)
    return out


def _weights(state: dict[str, torch.Tensor]) -> tuple[str, str, str]:
    """The keys of the first weight matrix, the first bias and the largest tensor."""
    matrix = next(k for k, v in state.items() if v.dim() >= 2)
    bias = next((k for k, v in state.items() if v.dim() == 1 and "bias" in k), matrix)
    largest = max(state, key=lambda k: float(state[k].abs().max()))
    return matrix, bias, largest


def tensor_variants(kind: str, ckpt: dict[str, Any]) -> Iterator[Variant]:
    """Damage to the weights: dtypes, scale, NaN and infinity, extra, missing, reshaped."""
    state = ckpt["state"]
    matrix, bias, largest = _weights(state)
    w = state[matrix]
    for dtype in (torch.complex64, torch.complex128, torch.bool, torch.int32, torch.int64,
                  torch.uint8, torch.float64, torch.float16, torch.bfloat16):
        yield Variant(f"{matrix} as {dtype}", "dtype", _replace(ckpt, ("state", matrix),
                                                                 w.to(dtype)))
    for factor in (1e3, 1e5, 1e8, -1e5):
        yield Variant(f"{largest} x {factor:g}", "scaled",
                      _replace(ckpt, ("state", largest), state[largest] * factor))
    yield Variant("every tensor x 1e5", "scaled",
                  {**ckpt, "state": {k: v * 1e5 for k, v in state.items()}})
    for key, value in ((matrix, math.nan), (matrix, math.inf), (bias, -math.inf),
                       (bias, math.nan)):
        bad = state[key].clone()
        bad.view(-1)[bad.numel() // 2] = value
        yield Variant(f"{key}[middle] = {value}", "nan-inf", _replace(ckpt, ("state", key), bad))
    big = torch.zeros(1_000_000)
    yield Variant("extra small tensor in the weights", "extra",
                  _replace(ckpt, ("state", "extra.weight"), torch.zeros(3)))
    yield Variant("extra 4 MB tensor in the weights", "extra",
                  _replace(ckpt, ("state", "padding"), big))
    yield Variant("extra 4 MB top-level tensor", "extra", {**ckpt, "payload": big})
    yield Variant("extra top-level text", "extra", {**ckpt, "note": "x"})
    if kind in SPARE_ENTRY:
        hidden = {"padding": torch.zeros(4 * sum(v.numel() for v in state.values()) + 300_000)}
        yield Variant(f"oversized tensor in {SPARE_ENTRY[kind]!r}", "extra",
                      {**ckpt, SPARE_ENTRY[kind]: hidden})
    yield Variant(f"missing {matrix}", "missing", _replace(ckpt, ("state", matrix), DELETE))
    yield Variant("missing every weight", "missing", {**ckpt, "state": {}})
    for key in ("state", "config"):
        yield Variant(f"missing {key}", "missing", _replace(ckpt, (key,), DELETE))
    yield Variant(f"{matrix} transposed", "shape",
                  _replace(ckpt, ("state", matrix), w.transpose(0, -1)))
    yield Variant(f"{matrix} one row short", "shape", _replace(ckpt, ("state", matrix), w[:-1]))
    yield Variant(f"{matrix} as a list", "type", _replace(ckpt, ("state", matrix), w.tolist()))
    yield Variant("state as a list", "type", {**ckpt, "state": list(state.values())})
    for key in (k for k in state if k.endswith("std")):
        yield Variant(f"{key} zero", "nan-inf",
                      _replace(ckpt, ("state", key), torch.zeros_like(state[key])))


def config_variants(ckpt: dict[str, Any], entry: str = "config") -> Iterator[Variant]:
    """A bad value for every field of the config, cycling through the sorts of bad value."""
    numbers = integers = 0

    def walk(values: dict[str, Any], path: tuple[str, ...]) -> Iterator[Variant]:
        nonlocal numbers, integers
        for key, value in values.items():
            where = (*path, key)
            if isinstance(value, dict):
                yield from walk(value, where)
                continue
            if isinstance(value, bool):
                bad, sort = "yes", "config-type"
            elif isinstance(value, int):
                bad = BAD_INTEGERS[integers % len(BAD_INTEGERS)]
                integers += 1
                sort = "config-range" if isinstance(bad, int) else "config-type"
            elif isinstance(value, float):
                bad = BAD_NUMBERS[numbers % len(BAD_NUMBERS)]
                numbers += 1
                sort = ("config-nan" if isinstance(bad, float) and not math.isfinite(bad)
                        else "config-range" if isinstance(bad, float) else "config-type")
            elif isinstance(value, (list, tuple)) and value and isinstance(value[0], float):
                bad, sort = [value[0], math.nan], "config-nan"
            elif isinstance(value, (list, tuple)):
                bad, sort = [1, 2], "config-type"
            else:
                bad, sort = 3, "config-type"
            yield Variant(f"{'.'.join(where)} = {bad!r}", sort, _replace(ckpt, where, bad))

    yield from walk(ckpt[entry], (entry,))
    yield Variant("unknown config key", "config-type", _replace(ckpt, (entry, "colour"), 1))
    yield Variant("config as text", "config-type", {**ckpt, entry: "tcn"})


def adam_state(kind: str, ckpt: dict[str, Any]) -> dict[str, Any]:
    """The state of Adam after one step on the network of a gait or QuaterNet checkpoint, as a
    training checkpoint (``last.pt``) holds it."""
    network = (GaitNetwork(GaitConfig.from_dict(ckpt["config"])) if kind == "gait"
               else QuaterNetwork(QuaterNetConfig.from_dict(ckpt["config"])))
    network.load_state_dict(ckpt["state"])
    optimizer = torch.optim.Adam(network.parameters())
    sum(p.sum() for p in network.parameters()).backward()
    optimizer.step()
    return optimizer.state_dict()


def kind_variants(kind: str, ckpt: dict[str, Any]) -> Iterator[Variant]:
    """Damage to what a kind keeps beside its weights (statistics, controls, codec)."""
    if kind == "classifier":
        for name in ("mean", "std", "embedding_mean"):
            yield Variant(f"{name} x 1e5", "scaled", {**ckpt, name: ckpt[name] * 1e5})
        yield Variant("std zero", "nan-inf", {**ckpt, "std": torch.zeros_like(ckpt["std"])})
        yield Variant("mean NaN", "nan-inf", {**ckpt, "mean": ckpt["mean"] * math.nan})
        yield Variant("mean complex", "dtype", {**ckpt, "mean": ckpt["mean"].to(torch.complex64)})
        yield Variant("mean bool", "dtype", {**ckpt, "mean": ckpt["mean"].bool()})
        yield Variant("precision complex", "dtype", {**ckpt, "embedding_precision":
                                                     ckpt["embedding_precision"].cfloat()})
        yield Variant("precision int", "dtype", {**ckpt, "embedding_precision":
                                                 ckpt["embedding_precision"].long()})
        for value in (math.nan, -1.0, 0.0, math.inf):
            yield Variant(f"temperature {value}", "nan-inf",
                          {**ckpt, "temperature": torch.tensor(value, dtype=torch.float64)})
        yield Variant("unsure distance NaN", "nan-inf",
                      {**ckpt, "unsure_distance": torch.tensor(math.nan, dtype=torch.float64)})
        yield Variant("unsure distance complex", "dtype",
                      {**ckpt, "unsure_distance": torch.tensor(1 + 1j)})
        yield Variant("metrics not JSON", "type", {**ckpt, "metrics": "{"})
        yield Variant("another format", "type", {**ckpt, "format": "emotive-emotion-classifier/1"})
    if kind in ("gait", "quaternet"):
        speed = list(ckpt["controls"]["speed"])
        for value in (math.nan, math.inf, 0.0, -1.0, 1e9):
            bad = [value, *speed[1:]]
            yield Variant(f"controls speed {value}", "nan-inf",
                          _replace(ckpt, ("controls", "speed"), bad))
        yield Variant("controls fps NaN", "config-nan", _replace(ckpt, ("controls", "fps"),
                                                                 math.nan))
        yield Variant("controls complex speed", "dtype",
                      _replace(ckpt, ("controls", "speed"), [complex(v, 1) for v in speed]))
        yield Variant("missing controls", "missing", _replace(ckpt, ("controls",), DELETE))
        adam = adam_state(kind, ckpt)
        moment = adam["state"][0]["exp_avg"]
        for name, bad in (
            ("NaN moment", _replace(adam, ("state", 0, "exp_avg"), moment * math.nan)),
            ("moment of another shape", _replace(adam, ("state", 0, "exp_avg"), moment[:1])),
            ("complex moment", _replace(adam, ("state", 0, "exp_avg"), moment.cfloat())),
            ("NaN step", _replace(adam, ("state", 0, "step"), torch.tensor(math.nan))),
            ("state of no parameter", _replace(adam, ("state", 10_000), {})),
            ("one parameter short", {**adam, "param_groups": [
                {**adam["param_groups"][0], "params": adam["param_groups"][0]["params"][:-1]}]}),
            ("NaN learning rate", {**adam, "param_groups": [
                {**adam["param_groups"][0], "lr": math.nan}]}),
            ("a list", [1, 2]),
        ):
            yield Variant(f"optimizer: {name}", "optimizer", {**ckpt, "optimizer": bad})
    if kind == "fcrbm":
        codec = ckpt["codec"]
        yield Variant("codec fps NaN", "config-nan", _replace(ckpt, ("codec", "fps"), math.nan))
        yield Variant("codec fps 0", "config-range", _replace(ckpt, ("codec", "fps"), 0.0))
        yield Variant("codec fps 1e5", "config-range", _replace(ckpt, ("codec", "fps"), 1e5))
        yield Variant("codec mover 999", "config-range", _replace(ckpt, ("codec", "mover"), 999))
        for name in ("mean", "constant"):
            yield Variant(f"codec {name} x 1e5", "scaled", _replace(
                ckpt, ("codec", name), [v * 1e5 for v in codec[name]]))
        yield Variant("codec std zero", "nan-inf",
                      _replace(ckpt, ("codec", "std"), [0.0] * len(codec["std"])))
        yield Variant("codec mean NaN", "nan-inf",
                      _replace(ckpt, ("codec", "mean"), [math.nan] * len(codec["mean"])))
        yield Variant("codec mean complex", "dtype",
                      _replace(ckpt, ("codec", "mean"), [complex(v, 1) for v in codec["mean"]]))
        yield Variant("codec keeps column 10000", "config-range",
                      _replace(ckpt, ("codec", "keep"), [10_000, *codec["keep"][1:]]))
        yield Variant("velocity of no weight", "extra", {**ckpt, "velocity": {"w": torch.ones(2)}})
        yield Variant("velocity NaN", "nan-inf", {**ckpt, "velocity": {
            k: torch.full_like(v, math.nan) for k, v in ckpt["state"].items()}})
        yield Variant("another kind", "type", {**ckpt, "kind": "gait"})


def rig_variants(kind: str, ckpt: dict[str, Any]) -> Iterator[Variant]:
    """The saved rig damaged: parents out of order, a parent past the joints, a name twice."""
    entry = {"gait": "controls", "quaternet": "controls", "fcrbm": "codec"}.get(kind)
    if entry is None:
        return
    rig = ckpt[entry]["skeleton"]
    parents, names = list(rig["parents"]), list(rig["names"])
    swapped = parents.copy()
    swapped[1], swapped[2] = len(parents) - 1, 1
    for name, key, value in (
        ("parents out of order", "parents", swapped),
        ("a parent past the joints", "parents", [*parents[:-1], len(parents) + 5]),
        ("a joint named twice", "names", [names[0], names[0], *names[2:]]),
    ):
        yield Variant(f"rig: {name}", "rig", _replace(ckpt, (entry, "skeleton", key), value))


def byte_variants(data: bytes) -> Iterator[Variant]:
    """Damage to the file's bytes, loaded as the shipped file (the fingerprint) or as a user's
    copy (the archive's CRC-32)."""
    rng = np.random.default_rng(0)
    for fraction in (0.0, 0.1, 0.5, 0.99):
        yield Variant(f"truncated to {fraction:.0%}", "truncated", data[:int(len(data) * fraction)],
                      shipped=True)
    yield Variant("last byte cut", "truncated", data[:-1], shipped=True)
    for seed in range(4):
        flipped = bytearray(data)
        for at in np.random.default_rng(seed).choice(len(data), 20, replace=False):
            flipped[at] ^= 1 << int(rng.integers(8))
        yield Variant(f"20 flipped bits (seed {seed})", "flipped-bytes", bytes(flipped),
                      shipped=True)
    for seed in range(4, 7):
        flipped = bytearray(data)
        for at in np.random.default_rng(seed).choice(len(data), 20, replace=False):
            flipped[at] ^= 1 << int(rng.integers(8))
        yield Variant(f"20 flipped bits in a user's copy (seed {seed})", "flipped-bytes",
                      bytes(flipped))
    yield Variant("one byte appended", "flipped-bytes", data + b"\0", shipped=True)
    yield Variant("zeros", "truncated", bytes(len(data)), shipped=True)
    yield Variant("text", "truncated", b"this is not a checkpoint\n", shipped=True)


def variants(kind: str, ckpt: dict[str, Any], data: bytes) -> list[Variant]:
    """Every damaged copy of one kind's shipped checkpoint."""
    return [*tensor_variants(kind, ckpt), *config_variants(ckpt), *kind_variants(kind, ckpt),
            *rig_variants(kind, ckpt), *byte_variants(data)]


@pytest.fixture(scope="module")
def shipped() -> dict[str, tuple[dict[str, Any], bytes]]:
    out = {}
    for kind, (path, _) in KINDS.items():
        data = path().read_bytes()
        out[kind] = torch.load(path(), map_location="cpu", weights_only=True), data
    return out


@pytest.fixture
def assets(tmp_path, monkeypatch) -> Path:
    """A copy of the shipped weights' folder (cards included), taken as the shipped one."""
    root = tmp_path / "assets"
    shutil.copytree(checkpoint_checks.assets_folder(), root)
    monkeypatch.setattr(checkpoint_checks, "assets_folder", lambda: root)
    return root


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_no_damaged_checkpoint_is_accepted_only_the_pristine_copies(shipped, assets, tmp_path,
                                                                    kind):
    file, load = KINDS[kind]
    ckpt, data = shipped[kind]
    copy = assets / file().parent.name / file().name
    assert load(copy) is not None, "the pristine copy of the shipped file"
    user = tmp_path / f"user-{kind}.pt"
    user.write_bytes(data)
    assert load(user) is not None, "the pristine copy as a user's checkpoint"
    if kind in ("gait", "quaternet"):
        torch.save({**ckpt, "optimizer": adam_state(kind, ckpt)}, user)
        assert load(user) is not None, "a training checkpoint with its optimizer"
    if kind == "fcrbm":
        momentum = {k: torch.zeros_like(v) for k, v in ckpt["state"].items()}
        torch.save({**ckpt, "velocity": momentum}, user)
        assert load(user) is not None, "a training checkpoint with its momentum"
    found = variants(kind, ckpt, data)
    refused: Counter[str] = Counter()
    accepted, untyped = [], []
    for k, variant in enumerate(found):
        path = copy if variant.shipped else tmp_path / f"{kind}-{k}.pt"
        if isinstance(variant.payload, bytes):
            path.write_bytes(variant.payload)
        else:
            torch.save(variant.payload, path)
        try:
            load(path)
        except ConfigError as exc:
            message = str(exc)
            assert "\n" not in message and str(path) in message, (variant.name, message)
            assert "Error(s) in loading" not in message, (variant.name, message)
            refused[variant.damage] += 1
        except Exception as exc:  # any other type is the failure looked for
            untyped.append(f"{variant.name}: {type(exc).__name__}: {exc}")
        else:
            accepted.append(variant.name)
    assert not accepted and not untyped, (accepted, untyped)
    assert sum(refused.values()) == len(found) >= 45, refused
    assert {"dtype", "scaled", "nan-inf", "extra", "missing", "shape", "truncated",
            "flipped-bytes", "config-nan", "config-range", "config-type"} <= set(refused)
    if kind != "classifier":
        assert refused["rig"] == 3, refused


def test_the_corpus_holds_at_least_165_variants(shipped):
    counts = Counter(v.damage for kind, (ckpt, data) in shipped.items()
                     for v in variants(kind, ckpt, data))
    assert sum(counts.values()) >= 165, counts


def test_flipped_bytes_in_a_shipped_file_are_a_fingerprint_mismatch(shipped, assets):
    _, data = shipped["gait"]
    copy = assets / "gait" / "emotive-gait.pt"
    flipped = bytearray(data)
    for at in np.random.default_rng(1).choice(len(data), 20, replace=False):
        flipped[at] ^= 0x01
    copy.write_bytes(bytes(flipped))
    with pytest.raises(ConfigError, match="differs from the fingerprint") as info:
        load_gait_model(copy)
    assert "reinstall emotive" in str(info.value)
