"""The model registry: entries, lazy loaders and their errors."""

from __future__ import annotations

import pytest

from emotive.models.registry import (
    KINDS,
    REGISTRY,
    ModelEntry,
    ModelError,
    get_model,
    model_names,
)

NAMES = ("gait", "gait-no-affective", "gait-no-root-loss", "quaternet", "fcrbm", "lgb", "mar",
         "zero-velocity", "classifier")


def test_every_model_is_registered_with_its_kinds():
    assert tuple(REGISTRY) == NAMES
    for entry in REGISTRY.values():
        assert entry.kinds and set(entry.kinds) <= set(KINDS)
        assert set(entry.loaders) == set(entry.kinds)
        assert entry.summary and entry.paper and entry.weights


def test_every_loader_resolves_to_a_callable_without_running_it():
    for entry in REGISTRY.values():
        for kind in entry.kinds:
            assert callable(entry.loader(kind)), (entry.name, kind)


def test_committed_weights_and_cards_exist():
    from importlib.resources import files

    root = files("emotive")
    for entry in REGISTRY.values():
        if entry.weights.startswith("assets/"):
            assert (root / entry.weights).is_file(), entry.name
        if entry.card is not None:
            assert (root / entry.card).is_file(), entry.name


def test_model_names_by_kind():
    assert model_names() == list(NAMES)
    assert model_names("generator") == ["gait", "gait-no-affective", "gait-no-root-loss",
                                        "fcrbm", "lgb"]
    assert model_names("predictor") == ["gait", "gait-no-affective", "gait-no-root-loss",
                                        "quaternet", "zero-velocity"]
    assert model_names("transfer") == ["mar"]
    assert model_names("classifier") == ["classifier"]
    with pytest.raises(ModelError, match="unknown model kind 'generators'"):
        model_names("generators")


def test_unknown_names_suggest_the_closest():
    with pytest.raises(ModelError, match=r"unknown model 'fcrmb' \(did you mean 'fcrbm'\?\)"):
        get_model("fcrmb")
    with pytest.raises(ModelError, match=r"use one of gait, .*classifier"):
        get_model("nothing-like-it")


def test_unknown_options_kinds_and_weights_are_errors():
    with pytest.raises(ModelError, match="'fcrbm' has no option rho: it takes gibbs, root"):
        get_model("fcrbm").load("generator", rho=0.5)
    with pytest.raises(ModelError, match="'gait' has no option gibbs: it takes raw"):
        get_model("gait").load("generator", gibbs=3)
    with pytest.raises(ModelError, match=r"'quaternet' is no generator: .* predictor"):
        get_model("quaternet").load("generator")
    with pytest.raises(ModelError, match="'zero-velocity' has no weights"):
        get_model("zero-velocity").load("predictor", weights="x.pt")


def test_options_given_as_none_are_ignored():
    predictor = get_model("zero-velocity").load("predictor", gibbs=None, rho=None)
    assert predictor.name == "Zero velocity"


def test_a_loader_that_cannot_be_imported_is_a_model_error():
    entry = ModelEntry("broken", ("predictor",), "s", "p", "none: -",
                       {"predictor": "emotive.no_such_module:load"})
    with pytest.raises(ModelError, match="'broken': its predictor loader"):
        entry.load("predictor")
    with pytest.raises(ValueError, match="must be among"):
        ModelEntry("bad", ("generator",), "s", "p", "w", {"predictor": "m:f"})


def test_the_models_command_lists_every_entry():
    import json

    import typer
    from typer.testing import CliRunner

    from emotive.commands.models import models

    app = typer.Typer()
    app.command()(models)
    table = CliRunner().invoke(app, [], terminal_width=200)
    assert table.exit_code == 0, table.output
    for name in NAMES:
        assert name in table.output
    rows = json.loads(CliRunner().invoke(app, ["--json"]).output)
    assert [r["name"] for r in rows] == list(NAMES)
    assert rows[4]["options"].keys() == {"gibbs", "root"}
