"""Checks a checkpoint passes before any of it reaches a network.

Every loader (gait network, QuaterNet, FCRBM, classifier) reads its file through
:func:`emotive.models.training.read_checkpoint`, which applies these checks and turns each
``ValueError`` into a one-line :class:`~emotive.errors.ConfigError` naming the file:

* :func:`check_fingerprint`: a shipped weight file (under ``emotive/assets``) has the sha256
  written in the model card beside it, so that any changed byte is caught, also those the value
  checks cannot see (a flipped low bit of a float).
* :func:`check_archive`: every record of the file's zip archive (``torch.save``'s format)
  matches the CRC-32 the archive stores for it, so that damaged bytes of any checkpoint, a
  user's included, are caught before unpickling.
* :func:`check_entries`: the top-level entries are those the checkpoint's kind writes, and the
  tensors outside the weights are no larger than a training checkpoint's optimizer and random
  state can be (:data:`EXTRA_BYTES_PER_WEIGHT_BYTE`).
* :func:`build_weights` and :func:`check_state`: the weights against the network the config
  declares, built first on PyTorch's ``meta`` device (shapes without memory, so a config of
  absurd sizes allocates nothing): the same keys, and for each tensor the same dtype (complex,
  bool and integer tensors in place of float ones are refused), the same shape, finite values
  and no value beyond :data:`WEIGHT_LIMIT`.
* :func:`check_optimizer`: a training checkpoint's optimizer state against the network's
  parameters (for ``--resume``).
* :func:`check_fields`: a config's fields by their annotations (``int``, ``float``, ``bool``,
  ``str``, tuples of them), floats finite, and each field of a table of :class:`Range` within
  it; the configs call it from ``__post_init__``, so a checkpoint's config and a TOML file's
  are checked alike.

User-trained checkpoints have no model card and so no fingerprint: they rely on the archive's
CRC-32 (accidental damage: flipped, zeroed or lost bytes) and on the value checks (wrong
types and absurd values); a file rewritten on purpose with plausible weights passes both.
"""

from __future__ import annotations

import hashlib
import math
import numbers
import re
import types
import typing
import zipfile
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, fields, is_dataclass
from importlib import resources
from pathlib import Path
from typing import Any, TypeVar

import torch

from emotive.errors import ConfigError

M = TypeVar("M", bound=torch.nn.Module)

#: Largest magnitude of any value in a network's state (weights and the feature statistics
#: stored with them), by default: about 100 times the shipped networks' trained range, so that
#: weights scaled by 100 or more, or a diverged training, are refused while a user's retraining
#: with other sizes or for longer keeps ample room. The gait network's largest value is 2.71
#: (its ``affective_mean``; its largest weight 2.08, a GRU input weight of the no-affective
#: ablation) and QuaterNet's 1.80, so 300 is 110 and 167 times theirs. Models whose weights are
#: smaller pass their own bound to :func:`build_weights` (the FCRBM's and the classifier's).
WEIGHT_LIMIT = 300.0

#: Bytes of tensors a checkpoint may hold outside its weights, per byte of weights: Adam's two
#: moments (2) or the FCRBM's momentum (1), plus one for slack. Random-number state and
#: statistics fit in :data:`EXTRA_BYTES_FREE`.
EXTRA_BYTES_PER_WEIGHT_BYTE = 3
#: Bytes of tensors outside the weights any checkpoint may hold (torch's random state is 5 kB).
EXTRA_BYTES_FREE = 1 << 20

#: A model card's fingerprint line: ``- sha256 of `FILE`: `HEX``` (the dash optional).
FINGERPRINT_LINE = re.compile(
    r"^(?:- )?sha256 of `(?P<file>[^`/]+)`: `(?P<sha>[0-9a-f]{64})`\s*$", re.MULTILINE
)


def assets_folder() -> Path:
    """The folder of the shipped weights (``emotive/assets``), one sub-folder per model."""
    return Path(str(resources.files("emotive") / "assets"))


def sha256_of(path: Path) -> str:
    """The sha256 of a file's bytes, as 64 lower-case hex digits."""
    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def card_fingerprints(card: Path) -> dict[str, str]:
    """``{file name: sha256}`` of the fingerprint lines of a model card (none if no card)."""
    if not card.is_file():
        return {}
    text = card.read_text(encoding="utf-8")
    return {m["file"]: m["sha"] for m in FINGERPRINT_LINE.finditer(text)}


def check_fingerprint(path: Path) -> None:
    """Check a shipped weight file against the sha256 in its model card.

    Files outside :func:`assets_folder` (a user's checkpoints) pass unchecked.

    Args:
        path: the checkpoint file.

    Raises:
        ConfigError: a shipped file whose card lacks its fingerprint line, or whose sha256
            differs from it; one line naming the file, both digests and the fix.
    """
    root = assets_folder().resolve()
    resolved = path.resolve()
    if not resolved.is_relative_to(root):
        return
    card = resolved.parent / "MODEL_CARD.md"
    expected = card_fingerprints(card).get(resolved.name)
    if expected is None:
        raise ConfigError(f"{path}: a shipped weight file without a fingerprint in {card}; add "
                          f"the line \"sha256 of `{resolved.name}`: `<sha256sum of the file>`\" "
                          "to the card, or reinstall emotive")
    actual = sha256_of(resolved)
    if actual != expected:
        raise ConfigError(f"{path}: sha256 {actual[:16]}... differs from the fingerprint "
                          f"{expected[:16]}... in {card.name}: the shipped weights are damaged "
                          "or were replaced; reinstall emotive (or restore the file from its "
                          "repository), or load your own file from another folder")


def check_archive(path: Path) -> None:
    """Check every record of a zip-format checkpoint against its stored CRC-32.

    ``torch.save`` writes a zip archive with a CRC-32 per record, which ``torch.load`` does
    not verify; Python's :mod:`zipfile` does. A file that is not a zip archive is left to
    ``torch.load`` (its legacy format, or not a checkpoint at all).

    Args:
        path: the checkpoint file.

    Raises:
        ValueError: a record whose bytes do not match its CRC-32, or an archive whose
            directory cannot be read; one line.
    """
    if not zipfile.is_zipfile(path):
        return
    try:
        with zipfile.ZipFile(path) as archive:
            bad = archive.testzip()
    except Exception as exc:  # zipfile raises BadZipFile, EOFError, zlib errors, ...
        raise ValueError(f"a damaged zip archive ({type(exc).__name__})") from None
    if bad is not None:
        raise ValueError(f"its record {bad!r} fails its CRC-32 check: the file is damaged")


def _describe(value: Any) -> str:
    """What an unexpected entry is, for a message: its type, and its size for a tensor."""
    if isinstance(value, torch.Tensor):
        return f"a {value.dtype} tensor of {_megabytes(_nbytes(value))}"
    return f"a {type(value).__name__}"


def _nbytes(tensor: torch.Tensor) -> int:
    """Bytes of a tensor's values."""
    return tensor.numel() * tensor.element_size()


def _megabytes(n: int) -> str:
    """A size in bytes for a message: bytes, kB or MB."""
    if n < 1000:
        return f"{n} bytes"
    return f"{n / 1e3:.3g} kB" if n < 1_000_000 else f"{n / 1e6:.3g} MB"


def tensor_bytes(value: Any) -> int:
    """Bytes of every tensor in ``value`` (a tensor, or dicts, lists and tuples of them)."""
    if isinstance(value, torch.Tensor):
        return _nbytes(value)
    if isinstance(value, dict):
        return sum(tensor_bytes(v) for v in value.values())
    if isinstance(value, (list, tuple)):
        return sum(tensor_bytes(v) for v in value)
    return 0


def check_entries(checkpoint: Mapping[str, Any], entries: Collection[str]) -> None:
    """Check that a checkpoint holds no entry its kind does not write, nor oversized extras.

    Args:
        checkpoint: the loaded dict.
        entries: the top-level keys the checkpoint's kind may hold.

    Raises:
        ValueError: an unexpected entry (named, with its size if a tensor), or tensors outside
            ``checkpoint["state"]`` larger than :data:`EXTRA_BYTES_PER_WEIGHT_BYTE` times the
            weights plus :data:`EXTRA_BYTES_FREE`.
    """
    unexpected = [k for k in checkpoint if k not in entries]
    if unexpected:
        key = unexpected[0]
        raise ValueError(f"holds an unexpected entry {key!r} ({_describe(checkpoint[key])}); "
                         f"a checkpoint of this kind holds only {', '.join(sorted(entries))}")
    weights = tensor_bytes(checkpoint.get("state"))
    extra = sum(tensor_bytes(v) for k, v in checkpoint.items() if k != "state")
    limit = EXTRA_BYTES_PER_WEIGHT_BYTE * weights + EXTRA_BYTES_FREE
    if extra > limit:
        raise ValueError(f"holds {_megabytes(extra)} of tensors besides its "
                         f"{_megabytes(weights)} of weights, more than the {_megabytes(limit)} "
                         "a checkpoint of this network can hold")


def check_tensor(got: Any, want: torch.Tensor, name: str, std: bool = False,
                 limit: float = WEIGHT_LIMIT) -> None:
    """Check one tensor of a state against the network's: type, dtype, shape, values.

    Args:
        got: the checkpoint's value.
        want: the network's tensor (on any device, ``meta`` included), or one of the dtype and
            shape expected (``torch.empty(shape, dtype=..., device="meta")``).
        name: how the message names it (``"state['fc.weight']"``).
        std: a standard deviation, every value above 0.
        limit: largest magnitude of a value (floating tensors).

    Raises:
        ValueError: the first problem, in one line.
    """
    if not isinstance(got, torch.Tensor):
        raise ValueError(f"{name} is a {type(got).__name__}, not a tensor")
    if got.dtype != want.dtype:
        raise ValueError(f"{name} is a {got.dtype} tensor, not {want.dtype}")
    if got.shape != want.shape:
        raise ValueError(f"{name} has shape {tuple(got.shape)} but the config needs "
                         f"{tuple(want.shape)}")
    if not got.is_floating_point() or got.numel() == 0:
        return
    values = got.detach()
    finite = torch.isfinite(values)
    if not bool(finite.all()):
        bad = values.reshape(-1)[~finite.reshape(-1)][0]
        raise ValueError(f"{name} holds {float(bad):g}, as from a diverged training or a "
                         "corrupt file")
    largest = float(values.abs().max())
    if largest > limit:
        raise ValueError(f"{name} holds {largest:g}, beyond the trained range (at most "
                         f"{limit:g}), as from a diverged training or a corrupt file")
    if std and not bool((values > 0).all()):
        raise ValueError(f"{name} holds {float(values.min()):g}; a standard deviation must be "
                         "above 0")


def check_bound(values: Any, name: str, limit: float = WEIGHT_LIMIT) -> None:
    """Check that no number of an array-like of real numbers exceeds ``limit`` in magnitude.

    For statistics kept beside the weights (a codec's means), after
    :func:`~emotive.models.training.check_values` has found them finite.

    Raises:
        ValueError: the largest magnitude, named, when beyond ``limit``.
    """
    array = torch.as_tensor(values, dtype=torch.float64)
    if array.numel() and float(array.abs().max()) > limit:
        raise ValueError(f"{name} holds {float(array.abs().max()):g}, beyond the trained range "
                         f"(at most {limit:g}), as from a diverged training or a corrupt file")


def check_state(declared: Mapping[str, torch.Tensor], state: Any, name: str = "state",
                limit: float = WEIGHT_LIMIT) -> None:
    """Check a checkpoint's weights against the tensors a network declares.

    Args:
        declared: the network's ``state_dict()`` (``meta`` tensors suffice).
        state: the checkpoint's weights.
        name: how the message names ``state``.
        limit: largest magnitude of a value (:data:`WEIGHT_LIMIT`, or the model's own).

    Raises:
        ValueError: not a dict, a missing or an unexpected key, or a tensor failing
            :func:`check_tensor` (those of a key ending in ``std``, standard deviations of
            the features, also at or below 0); one line.
    """
    if not isinstance(state, dict):
        raise ValueError(f"{name} is a {type(state).__name__}, not a dict of tensors")
    missing = [k for k in declared if k not in state]
    if missing:
        raise ValueError(f"{name} lacks {missing[0]!r} ({len(missing)} of the network's "
                         f"{len(declared)} tensors missing): the weights do not match the config")
    unexpected = [k for k in state if k not in declared]
    if unexpected:
        raise ValueError(f"{name} holds {unexpected[0]!r} ({_describe(state[unexpected[0]])}), "
                         "which the network of the config lacks: the weights do not match the "
                         "config")
    for key, want in declared.items():
        check_tensor(state[key], want, f"{name}[{key!r}]", std=key.endswith("std"), limit=limit)


def build_weights(make: Callable[[], M], state: Any, name: str = "state",
                  limit: float = WEIGHT_LIMIT) -> M:
    """The network ``make()`` builds, with ``state`` loaded after :func:`check_state`.

    ``make`` runs first on the ``meta`` device, so the checked shapes cost no memory and a
    config of absurd sizes allocates nothing before its weights are refused.

    Args:
        make: builds the network of the checkpoint's config.
        state: the checkpoint's weights.
        name: how the message names ``state``.
        limit: largest magnitude of a value (:data:`WEIGHT_LIMIT`, or the model's own).

    Returns:
        The network, weights loaded (in the mode ``make`` left it).

    Raises:
        ValueError: as :func:`check_state`.
    """
    with torch.device("meta"):
        declared = make().state_dict()
    check_state(declared, state, name, limit)
    module = make()
    module.load_state_dict(state)
    return module


def check_optimizer(saved: Any, module: torch.nn.Module, name: str = "optimizer") -> None:
    """Check a training checkpoint's optimizer state against the network's parameters.

    The state of a ``torch.optim`` optimizer (Adam's): parameter groups that together index
    every parameter of ``module`` once, finite settings, and per parameter finite moments of
    the parameter's dtype and shape, so that ``--resume`` never loads moments of another
    network or NaN into the optimizer.

    Args:
        saved: ``optimizer.state_dict()`` as the checkpoint holds it.
        module: the network built from the checkpoint.
        name: how the message names ``saved``.

    Raises:
        ValueError: the first problem, named, in one line.
    """
    if not isinstance(saved, dict) or not isinstance(saved.get("state"), dict) or (
        not isinstance(saved.get("param_groups"), list)
    ):
        raise ValueError(f"{name} is not an optimizer's state ('state' and 'param_groups')")
    params = list(module.parameters())
    indices: list[Any] = []
    for group in saved["param_groups"]:
        if not isinstance(group, dict) or not isinstance(group.get("params"), list):
            raise ValueError(f"{name} holds a parameter group without its 'params' list")
        indices.extend(group["params"])
        for key, value in group.items():
            if key != "params" and not _finite_setting(value):
                raise ValueError(f"{name} setting {key!r} is {_shown(value)}, not a finite "
                                 "number")
    integers = all(isinstance(i, int) and not isinstance(i, bool) for i in indices)
    if not integers or sorted(indices) != list(range(len(params))):
        raise ValueError(f"{name} is for {len(indices)} parameters, not the network's "
                         f"{len(params)}")
    for index, entry in saved["state"].items():
        if not isinstance(index, int) or not 0 <= index < len(params) or (
            not isinstance(entry, dict)
        ):
            raise ValueError(f"{name} holds the state of {_shown(index)}, no parameter of the "
                             "network")
        for key, value in entry.items():
            where = f"{name}['state'][{index}][{key!r}]"
            if isinstance(value, torch.Tensor) and value.dim() == 0:
                if not (value.is_floating_point() and bool(torch.isfinite(value))):
                    raise ValueError(f"{where} is {_shown(value)}, not a finite number")
            else:
                check_tensor(value, params[index], where, limit=math.inf)


def _finite_setting(value: Any) -> bool:
    """Whether an optimizer setting is a bool, ``None``, or finite numbers."""
    if value is None or isinstance(value, bool):
        return True
    if isinstance(value, (tuple, list)):
        return all(_finite_setting(v) for v in value)
    return isinstance(value, numbers.Real) and math.isfinite(value)


@dataclass(frozen=True)
class Range:
    """Closed interval a config number must lie in (``above``: open at ``low``).

    Attributes:
        low: smallest value.
        high: largest value.
        above: ``low`` itself is refused (a rate or a length that must be positive).
    """

    low: float
    high: float
    above: bool = False

    def holds(self, value: float) -> bool:
        """Whether ``value`` lies in the range."""
        low_ok = value > self.low if self.above else value >= self.low
        return low_ok and value <= self.high

    def __str__(self) -> str:
        return f"{'(' if self.above else '['}{self.low:g}, {self.high:g}]"


#: The seeds a config may give (those of ``--seed``).
SEED_RANGE = Range(0, 2**32 - 1)
#: Frame rates a config may give, frames per second (motion capture runs at 30 to 240).
FPS_RANGE = Range(1, 1000)
#: Layer widths a config may give: the shipped networks' widest layer is 1,000 units.
WIDTH_RANGE = Range(1, 16384)
#: Weights of loss terms (the shipped configs use 0.01 to 3).
LOSS_WEIGHT_RANGE = Range(0, 1000)


def _kind_error(value: Any, want: Any) -> str | None:
    """Why ``value`` is not of the annotation ``want``, or ``None`` when it is."""
    origin = typing.get_origin(want)
    if want is bool:
        return None if isinstance(value, bool) else "must be true or false"
    if want is int:
        ok = isinstance(value, numbers.Integral) and not isinstance(value, bool)
        return None if ok else "must be an integer"
    if want is float:
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            return "must be a number"
        return None if math.isfinite(value) else "must be a finite number"
    if want is str:
        return None if isinstance(value, str) else "must be a text"
    if origin is tuple:
        if not isinstance(value, (tuple, list)):
            return "must be a list"
        args = typing.get_args(want)
        kinds = [args[0]] * len(value) if len(args) == 2 and args[1] is Ellipsis else list(args)
        if len(kinds) != len(value):
            return f"must be a list of {len(kinds)} values"
        for k, (item, kind) in enumerate(zip(value, kinds, strict=True)):
            reason = _kind_error(item, kind)
            if reason is not None:
                return f"item {k} ({item!r}) {reason}"
        return None
    if origin in (types.UnionType, typing.Union):
        reasons = [_kind_error(value, a) for a in typing.get_args(want)]
        return None if None in reasons else reasons[0]
    if want is type(None):
        return None if value is None else "must be empty"
    if isinstance(want, type) and not isinstance(value, want):
        return f"must be a {want.__name__}"
    return None


def _shown(value: Any) -> str:
    """A value for a message, at most 40 characters."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def check_fields(config: Any, ranges: Mapping[str, Range] | None = None) -> None:
    """Check the field values of a dataclass config by its annotations and ``ranges``.

    Called without ``ranges`` first in ``__post_init__`` (types only, before the config's own
    checks and conversions), then with them at its end. Each field must be of its annotation
    (an ``int`` field an integer, not a bool; a ``float`` field a finite number, an integer
    allowed; ``bool``, ``str``, ``tuple[X, ...]`` and ``X | None`` alike; a nested dataclass
    is checked by its own class); a field of ``ranges`` (and its items, for a tuple) must lie
    in its :class:`Range`.

    Args:
        config: a dataclass instance.
        ranges: ``{field name: range}``.

    Raises:
        ValueError: ``"Config.field must be ..., got value"``, the first bad field (the form
            :func:`~emotive.models.training.load_settings` names the TOML key by).
    """
    if not is_dataclass(config):
        raise TypeError(f"{type(config).__name__} is not a dataclass")
    cls = type(config).__name__
    hints = typing.get_type_hints(type(config))
    ranges = ranges or {}
    for f in fields(config):
        value = getattr(config, f.name)
        reason = _kind_error(value, hints.get(f.name, Any))
        if reason is not None:
            raise ValueError(f"{cls}.{f.name} {reason}, got {_shown(value)}")
        bound = ranges.get(f.name)
        if bound is None or value is None:
            continue
        for item in value if isinstance(value, (tuple, list)) else (value,):
            if not bound.holds(item):
                raise ValueError(f"{cls}.{f.name} must be in {bound}, got {_shown(value)}")
