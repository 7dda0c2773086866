"""The shipped training recipes: installed with the package, the default of every ``train``."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from emotive.configs import recipe_names, recipe_path, resolve_config
from emotive.errors import ConfigError
from emotive.models.gait.training import load_gait_settings

REPO = Path(__file__).resolve().parents[2]
PACKAGE = REPO / "src" / "emotive" / "configs"


def test_every_recipe_ships_in_the_package_and_the_repo_folder_is_the_same_files():
    names = recipe_names()
    assert {"gait", "gait-finetune", "quaternet", "fcrbm", "classifier"} <= set(names)
    assert sorted(p.stem for p in PACKAGE.glob("*.toml")) == names
    assert (REPO / "configs").resolve() == PACKAGE.resolve()
    for name in names:
        assert recipe_path(name).read_bytes() == (PACKAGE / f"{name}.toml").read_bytes()


def test_a_config_value_is_a_file_when_one_exists_else_a_recipe_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert resolve_config("gait") == recipe_path("gait")
    (tmp_path / "gait").write_text("[model]\n")
    assert resolve_config("gait") == Path("gait")
    assert resolve_config("mine.toml") == Path("mine.toml")
    with pytest.raises(ConfigError, match=r"--config gaitt: no such file.*gait-finetune"):
        resolve_config("gaitt")
    with pytest.raises(ConfigError, match=r"no shipped recipe named 'nope'"):
        recipe_path("nope")


def test_the_fine_tuning_recipe_finds_the_shipped_first_stage_from_any_folder(tmp_path,
                                                                             monkeypatch):
    monkeypatch.chdir(tmp_path)
    _, settings = load_gait_settings(resolve_config("gait-finetune"))
    stage1 = Path(settings.init_from)
    assert stage1.is_absolute() and stage1.is_file()
    assert stage1.name == "emotive-gait-stage1.pt"


def test_a_relative_init_from_is_read_from_the_recipes_own_folder(tmp_path, monkeypatch):
    text = recipe_path("gait-finetune").read_text(encoding="utf-8")
    mine = tmp_path / "recipes" / "mine.toml"
    mine.parent.mkdir()
    mine.write_text(text.replace('init_from = "../assets/gait/emotive-gait-stage1.pt"',
                                 'init_from = "start/first.pt"'), encoding="utf-8")
    monkeypatch.chdir(REPO)
    _, settings = load_gait_settings(os.path.relpath(mine))
    assert Path(settings.init_from) == mine.parent / "start" / "first.pt"
