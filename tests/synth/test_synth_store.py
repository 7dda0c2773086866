"""The data set folder: one recipe per folder, one run at a time, leftovers of a killed run
removed, a shard counted finished only when its whole file is there."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.synth import store
from emotive.synth.recipe import Recipe
from emotive.synth.shards import npz_bytes, shard_name

VALUES = Recipe(paths=1, emotions=2, transitions=0, seconds=2.0).to_dict()


def test_a_new_folder_is_created_and_a_foreign_one_refused(tmp_path):
    folder = store.open_folder(tmp_path / "new" / "set", VALUES)
    assert folder.created and folder.root.is_dir()
    store.discard(folder)
    assert not (tmp_path / "new" / "set").exists()
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("x")
    with pytest.raises(store.FolderError) as exc:
        store.open_folder(tmp_path / "mine", VALUES)
    assert "holds notes.txt and no recipe.json; give a new or empty folder" in str(exc.value)
    (tmp_path / "file").write_text("x")
    with pytest.raises(store.FolderError, match="it is a file"):
        store.open_folder(tmp_path / "file", VALUES)


def test_another_recipe_is_refused_naming_the_difference(tmp_path):
    folder = store.open_folder(tmp_path, VALUES)
    store.write_recipe(folder, {"checked": False})
    folder.close()
    with pytest.raises(store.FolderError) as exc:
        store.open_folder(tmp_path, {**VALUES, "seed": 3})
    message = str(exc.value)
    assert "holds another recipe (seed 0 there, 3 here)" in message and "\n" not in message
    store.open_folder(tmp_path, VALUES).close()


def test_one_run_at_a_time(tmp_path):
    first = store.open_folder(tmp_path, VALUES)
    with pytest.raises(store.FolderError, match="another emotive synth is writing it"):
        store.open_folder(tmp_path, VALUES)
    first.close()
    store.open_folder(tmp_path, VALUES).close()


def test_leftovers_removed_and_only_whole_shards_of_this_recipe_count(tmp_path):
    folder = store.open_folder(tmp_path, VALUES)
    store.write_recipe(folder, {"checked": False})
    folder.write_files({shard_name(0): npz_bytes({"recipe_id": np.array(folder.recipe_id)})})
    folder.write_files({shard_name(1): npz_bytes({"recipe_id": np.array("another")})})
    (tmp_path / shard_name(2)).write_bytes(b"PK\x03\x04 truncated")
    left = tmp_path / "shards" / ".shard-00003.npz.a1b2c3d4.tmp.npz"
    left.write_bytes(b"half")
    folder.close()
    folder = store.open_folder(tmp_path, VALUES)
    assert not left.exists()
    assert folder.done_shards(4) == {0}
    folder.close()
