"""The manifest's schema and the card's statements, from rows alone (no model run)."""

from __future__ import annotations

import math

import pytest

from emotive.synth import card, manifest
from emotive.synth.build import recipe_values
from emotive.synth.recipe import Recipe
from emotive.synth.trajectories import trajectory


def _rows(follows_paths: bool = True, blends: bool = True) -> list[dict]:
    rows = []
    for i in range(3):
        weights = [0.5, 0.2, 0.2, 0.1] if blends else [1.0, 0.0, 0.0, 0.0]
        rows.append({
            "sample_id": 2 - i, "shard": 0, "kind": "constant", "path_id": 0,
            "emotion_id": 2 - i, "transition_from": -1, "transition_to": -1,
            "transition_time": math.nan, "transition_seconds": math.nan, "emotion": weights,
            "emotion_end": weights, "valence": 0.1, "arousal": 0.2, "valence_end": 0.1,
            "arousal_end": 0.2, "seed": 0, "walk_seed": 5, "sha256": f"{i:064x}",
            "perceived": "happy" if i else "sad", "perceived_probability": 0.8,
            "perceived_valence": 0.3, "perceived_arousal": 0.1, "unsure": i == 2,
            "foot_skate": 0.02, "foot_skate_ratio": 0.05,
            "path_deviation": 0.001 if follows_paths else math.nan,
            "path_deviation_max": 0.002 if follows_paths else math.nan,
            "heading_deviation": 5.0 if follows_paths else math.nan,
            "frames": 121, "fps": 30.0, "seconds": 4.0, "model": "gait",
        })
    return rows


@pytest.fixture(scope="module")
def values() -> dict:
    return recipe_values(Recipe(paths=1, emotions=3, transitions=0, seconds=4.0))


def test_manifest_is_sorted_and_typed(values):
    table = manifest.table(_rows(), values)
    assert table.column("sample_id").to_pylist() == [0, 1, 2]
    assert table.schema.field("emotion").type.list_size == 4
    assert table.column("bvh").null_count == 3
    assert b"emotive.recipe" in table.schema.metadata


def test_card_states_licence_counts_and_a_skipped_check(values):
    paths = [trajectory(0, 0, 4.0).summary()]
    skipped = {"checked": False, "reason": "the data set bandai-namco-1 is not available",
               "paths": []}
    text = card.card_text(values, skipped, manifest.table(_rows(), values), paths, "abc")
    assert "CC BY-NC 4.0" in text and "non-commercial use only" in text
    assert "**3 walks**" in text and "1 trajectory x 3 emotions" in text
    assert "**The check against the data was skipped**: the data set bandai-namco-1" in text
    assert "blend's heaviest label for 66.7% of 3" in text
    assert "unsure: 1 of 3 walks" in text
    assert "walks freely" not in text and "one label at a time" not in text


def test_card_says_what_a_model_could_not_honour(values):
    table = manifest.table(_rows(follows_paths=False, blends=False), values)
    text = card.card_text({**values, "weights": "none: fitted on each use"},
                          {"checked": False, "reason": "x", "paths": []}, table,
                          [trajectory(0, 0, 4.0).summary()], "abc")
    assert "This model walks freely" in text and "one label at a time" in text
    assert "directly from the Bandai Namco" in text
    assert "root's distance from the path (m), mean per walk: not measured" in text


def test_card_states_a_check_and_the_draws_taken(values):
    paths = [trajectory(0, 0, 4.0, 2).summary()]
    checked = {"checked": True, "reason": "", "clips": 1061,
               "datasets": ["bandai-namco-1", "bandai-namco-2-locomotion"],
               "match_fraction": 0.03, "min_coverage": 0.8, "max_draws": 50, "step_m": 0.25,
               "paths": [{"path_id": 0, "nearest_clip": "dataset-2_walk_normal_001",
                          "distance_m": 0.41, "coverage": 0.9, "coincides": False,
                          "relative_gap": 0.052, "draw": 2}]}
    text = card.card_text(values, checked, manifest.table(_rows(), values), paths, "abc")
    assert "within a mean gap of 3% of the length compared" in text
    assert "at least 80% of the trajectory. None coincides. 1 trajectory was drawn again" in text
    assert "(gap 0.41 m, 5.2% of the length compared, over 90% of the trajectory)" in text
    assert "| 0 | 2 | " in text and "`dataset-2_walk_normal_001` | 0.41 | 90% |" in text
