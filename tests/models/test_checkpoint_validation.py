"""Every checkpoint loader checks its file field by field: corrupt variants of each committed
checkpoint (a missing entry, a wrong shape, NaN or absurd weights, a zero standard deviation,
NaN controls, a NaN config value, a bare tensor, a truncated or non-torch file) are one-line
ConfigErrors through the API, and one ``error:`` line with exit code 2 through the command
line."""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import torch

from cli_helpers import run_main
from emotive.errors import ConfigError
from emotive.eval.classifier import EmotionClassifier, default_classifier_path
from emotive.models.fcrbm.checkpoint import load_fcrbm_checkpoint
from emotive.models.fcrbm.generate import default_checkpoint_path as fcrbm_checkpoint_path
from emotive.models.gait.model import default_checkpoint_path as gait_checkpoint_path
from emotive.models.gait.model import load_gait_model
from emotive.models.gait.quaternet.adapter import (
    default_checkpoint_path as quaternet_checkpoint_path,
)
from emotive.models.gait.quaternet.training import load_quaternet_checkpoint
from emotive.models.training import MAX_MAGNITUDE, check_values

#: name: (committed file, loader, keys a variant deletes, where its standard deviation is).
LOADERS: dict[str, tuple[Callable[[], Path], Callable[[Path], Any], tuple[str, ...], str]] = {
    "gait": (gait_checkpoint_path, load_gait_model, ("config", "state"), "state.root_std"),
    "quaternet": (quaternet_checkpoint_path, load_quaternet_checkpoint, ("config", "state"),
                  "state.movement_std"),
    "fcrbm": (fcrbm_checkpoint_path, load_fcrbm_checkpoint, ("config", "state", "codec"),
              "codec.std"),
    "classifier": (default_classifier_path, EmotionClassifier.load,
                   ("config", "state", "mean", "std", "metrics"), "std"),
}


@pytest.fixture(scope="module")
def committed() -> dict[str, dict[str, Any]]:
    return {name: torch.load(spec[0](), map_location="cpu", weights_only=True)
            for name, spec in LOADERS.items()}


def first_weight(state: dict[str, torch.Tensor]) -> str:
    return next(k for k, v in state.items() if v.is_floating_point() and v.dim() >= 2)


def with_value(ckpt: dict[str, Any], value: float) -> dict[str, Any]:
    bad = copy.deepcopy(ckpt)
    key = first_weight(bad["state"])
    bad["state"][key] = bad["state"][key].clone()
    bad["state"][key].view(-1)[3] = value
    return bad


def with_zero_std(ckpt: dict[str, Any], where: str) -> dict[str, Any]:
    bad = copy.deepcopy(ckpt)
    *outer, key = where.split(".")
    holder = bad[outer[0]] if outer else bad
    if isinstance(holder[key], list):
        holder[key][2] = 0.0
    else:
        holder[key] = holder[key].clone()
        holder[key][2] = 0.0
    return bad


def variants(name: str, ckpt: dict[str, Any]) -> dict[str, tuple[Any, str]]:
    """Corrupt copies of a checkpoint: ``variant: (object to save, words of the message)``."""
    _, _, keys, std_at = LOADERS[name]
    out: dict[str, tuple[Any, str]] = {}
    for key in keys:
        out[f"missing-{key}"] = ({k: v for k, v in ckpt.items() if k != key},
                                 f"no '{key}' entry")
    shaped = copy.deepcopy(ckpt)
    key = first_weight(shaped["state"])
    shaped["state"][key] = shaped["state"][key][..., :1].clone()
    out["wrong-shape"] = (shaped, f"state['{key}'] has shape")
    out["nan-weight"] = (with_value(ckpt, math.nan), "holds nan")
    out["inf-weight"] = (with_value(ckpt, -math.inf), "holds -inf")
    out["absurd-weight"] = (with_value(ckpt, 1e30), "holds 1e+30, beyond the trained range")
    out["zero-std"] = (with_zero_std(ckpt, std_at), "a standard deviation must be above 0")
    out["config-not-a-dict"] = ({**ckpt, "config": "tcn"}, "'config' is a str, not a dict")
    out["bare-tensor"] = (torch.zeros(3), "holds a Tensor, not a dict")
    # A NaN frame rate once reached `emotive classify` as "cannot convert float NaN to integer".
    field = "init_std" if name == "fcrbm" else "fps"
    out["config-nan"] = ({**ckpt, "config": {**ckpt["config"], field: math.nan}},
                         f"{field} must be")
    if "controls" in ckpt:
        controls = copy.deepcopy(ckpt)
        controls["controls"]["speed"][1] = math.nan
        out["nan-controls"] = (controls, "controls['speed'] holds nan")
        out["missing-controls"] = ({k: v for k, v in ckpt.items() if k != "controls"},
                                   "without animation controls")
    if name == "classifier":
        short = copy.deepcopy(ckpt)
        short["mean"] = short["mean"][:5].clone()
        out["mean-shape"] = (short, "'mean' has shape (5,) but the config needs (152,)")
    return out


def write_variants(name: str, ckpt: dict[str, Any], folder: Path) -> list[tuple[Path, str]]:
    files = []
    for variant, (obj, words) in variants(name, ckpt).items():
        path = folder / f"{name}-{variant}.pt"
        torch.save(obj, path)
        files.append((path, words))
    data = LOADERS[name][0]().read_bytes()
    truncated = folder / f"{name}-truncated.pt"
    truncated.write_bytes(data[: len(data) // 2])
    text = folder / f"{name}-text.pt"
    text.write_text("this is not a checkpoint\n")
    return [*files, (truncated, "not a PyTorch file"), (text, "not a PyTorch file")]


def test_the_committed_checkpoints_pass(committed):
    for name, (path, load, _, _) in LOADERS.items():
        assert load(path()) is not None, name


@pytest.mark.parametrize("name", sorted(LOADERS))
def test_every_corrupt_variant_is_a_one_line_config_error(committed, tmp_path, name):
    load = LOADERS[name][1]
    for path, words in write_variants(name, committed[name], tmp_path):
        with pytest.raises(ConfigError) as info:
            load(path)
        message = str(info.value)
        assert "\n" not in message and str(path) in message, message
        assert words in message, (path.name, message)
        # torch's own multi-line reports never show through.
        assert "Error(s) in loading" not in message and "miniz" not in message


@pytest.mark.parametrize(("name", "args"), [
    ("gait", ["generate", "--seconds", "0.5", "--checkpoint"]),
    ("fcrbm", ["generate", "--model", "fcrbm", "--seconds", "0.5", "--checkpoint"]),
    ("classifier", ["classify", "in/clip.bvh", "--model"]),
])
def test_the_command_line_prints_one_error_line_and_exits_2(committed, tmp_path, monkeypatch,
                                                            capsys, name, args):
    folder = tmp_path / "in"
    folder.mkdir()
    (folder / "clip.bvh").write_text("")  # classify checks that its clip exists first
    monkeypatch.chdir(tmp_path)
    for path, words in write_variants(name, committed[name], folder):
        extra = ["-o", tmp_path / "out.bvh"] if args[0] == "generate" else []
        code, out, err = run_main(monkeypatch, capsys, *args, path, *extra)
        assert code == 2 and out == "", (path.name, code, err)
        assert err.startswith("error: ") and err.count("\n") == 1, err
        assert words in err, (path.name, err)
        assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]


def test_check_values_walks_nested_entries_and_names_the_bad_one():
    check_values({"a": [1.0, [2.0, 3.0]], "b": "text", "c": None, "d": torch.ones(2, 2)}, "x")
    check_values([MAX_MAGNITUDE, -MAX_MAGNITUDE], "x")
    for value, words in (({"a": {"b": [1.0, math.nan]}}, "x['a']['b'] holds nan"),
                         ({"s": {"names": ["a"], "offsets": [[0, 1], [0, math.inf]]}},
                          "x['s']['offsets'] holds inf"),
                         (torch.tensor([1.0, 2e6]), "beyond the plausible")):
        with pytest.raises(ValueError, match=words.replace("[", r"\[")):
            check_values(value, "x")
    with pytest.raises(ValueError, match="above 0"):
        check_values(torch.tensor([1.0, 0.0]), "std", positive=True)
