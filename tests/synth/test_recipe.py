"""The recipe: counts, the sample layout, fixed shards, and bad numbers refused in one line."""

from __future__ import annotations

import pytest

from emotive.synth.recipe import Recipe, SynthError, check_formats, named_recipe, recipe_id

SMALL = {"paths": 2, "emotions": 3, "transitions": 1, "seconds": 4.0}


def test_the_paper_recipe_is_the_default():
    recipe = Recipe()
    assert (recipe.paths, recipe.emotions, recipe.transitions, recipe.seconds) == (20, 100, 50,
                                                                                   10.0)
    assert (recipe.constant_walks, recipe.transition_walks, recipe.total) == (2000, 1000, 3000)
    assert recipe.shards == 30


def test_small_recipe_has_eight_walks_in_order():
    recipe = Recipe(**SMALL, shard_size=3)
    assert recipe.total == 8
    specs = [recipe.sample(i) for i in range(8)]
    assert [(s.path, s.emotion) for s in specs[:6]] == [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1),
                                                       (1, 2)]
    assert [(s.path, s.pair, s.is_transition) for s in specs[6:]] == [(0, 0, True),
                                                                     (1, 0, True)]
    assert [list(recipe.shard_range(s)) for s in range(recipe.shards)] == [[0, 1, 2],
                                                                         [3, 4, 5], [6, 7]]
    with pytest.raises(IndexError):
        recipe.sample(8)


def test_named_recipes_and_their_changes():
    assert named_recipe("paper") == Recipe()
    small = named_recipe("small")
    assert small == Recipe(**SMALL) and small.total == 8
    short = named_recipe("small", seconds=3.0, seed=7, paths=None)
    assert (short.paths, short.seconds, short.seed, short.total) == (2, 3.0, 7, 8)
    with pytest.raises(SynthError, match="--recipe tiny: no such recipe; give one of paper, "
                                         "small"):
        named_recipe("tiny")


def test_round_trip_and_id():
    recipe = Recipe(**SMALL, formats=("glb", "bvh"))
    values = recipe.to_dict({"extra": 1})
    assert Recipe.from_dict(values) == recipe
    assert values["formats"] == ["npz", "bvh", "glb"]
    assert recipe_id(values) == recipe_id(dict(reversed(values.items())))
    assert recipe_id(values) != recipe_id({**values, "seed": 1})


@pytest.mark.parametrize(("changes", "words"), [
    ({"paths": 0}, ["--paths 0", "whole number from 1"]),
    ({"emotions": -3}, ["--emotions -3"]),
    ({"transitions": -1}, ["--transitions -1"]),
    ({"transitions": 2}, ["--transitions 2", "at most 1 disjoint pairs", "--transitions 1"]),
    ({"seconds": 0.5}, ["--seconds 0.5"]),
    ({"seconds": float("nan")}, ["--seconds nan"]),
    ({"shard_size": 0}, ["--shard-size 0"]),
    ({"seed": -1}, ["--seed -1"]),
    ({"paths": 2.5}, ["--paths 2.5"]),
])
def test_bad_numbers_are_one_line_errors(changes, words):
    with pytest.raises(SynthError) as exc:
        Recipe(**{**SMALL, **changes})
    message = str(exc.value)
    assert "\n" not in message and all(w in message for w in words), message


def test_formats():
    assert check_formats("bvh") == ("npz", "bvh")
    assert check_formats(" NPZ , .glb") == ("npz", "glb")
    with pytest.raises(SynthError, match="--formats fbx: unknown fbx"):
        check_formats("fbx")
