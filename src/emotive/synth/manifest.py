"""``manifest.parquet``: one row per walk of a synthetic data set.

The table of the main paper's augmented data set (Bhattacharya et al. 2020, section 5.2) as
this toolkit makes it; ``pandas.read_parquet(DIR / "manifest.parquet")`` reads it. Columns
(:data:`SCHEMA`), one row per walk in sample order:

* what it is: ``sample_id``, ``shard``, ``kind`` (``constant`` or ``transition``),
  ``path_id``, ``emotion_id`` (-1 for a transition), ``transition_from``, ``transition_to``
  (emotion ids, -1 for a constant walk), ``transition_time`` and ``transition_seconds``
  (when the change starts and how long it takes, seconds; NaN for a constant walk),
  ``seed`` (the recipe's), ``walk_seed`` (the walk's own, from the seed and ``sample_id``);
* its emotion: ``emotion`` and ``emotion_end`` (weights over happy, sad, angry, neutral at
  the first and last frame), ``valence``, ``arousal``, ``valence_end``, ``arousal_end``
  (-1..1);
* ``sha256`` of its arrays (:func:`emotive.synth.shards.walk_digest`);
* its measures (:mod:`emotive.synth.measures`): ``perceived``, ``perceived_probability``,
  ``perceived_valence``, ``perceived_arousal``, ``unsure``, ``foot_skate`` (m/s),
  ``foot_skate_ratio``, ``path_deviation``, ``path_deviation_max`` (m),
  ``heading_deviation`` (degrees);
* ``frames``, ``fps``, ``seconds``, ``model``, and ``bvh``, ``glb``: its files (relative, null
  when not written).

The file's metadata holds the recipe (``emotive.recipe``, JSON) and the label order
(``emotive.labels``).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from emotive.io.atomic import atomic_output
from emotive.synth.emotions import LABELS

_INT = ("sample_id", "shard", "path_id", "emotion_id", "transition_from", "transition_to",
        "seed", "walk_seed", "frames")
_FLOAT = ("transition_time", "transition_seconds", "valence", "arousal", "valence_end",
          "arousal_end", "perceived_probability", "perceived_valence", "perceived_arousal",
          "foot_skate", "foot_skate_ratio", "path_deviation", "path_deviation_max",
          "heading_deviation", "fps", "seconds")
_TEXT = ("kind", "sha256", "perceived", "model", "bvh", "glb")
#: Column order of the manifest.
COLUMNS = (
    "sample_id", "shard", "kind", "path_id", "emotion_id", "transition_from", "transition_to",
    "transition_time", "transition_seconds", "emotion", "emotion_end", "valence", "arousal",
    "valence_end", "arousal_end", "seed", "walk_seed", "sha256", "perceived",
    "perceived_probability", "perceived_valence", "perceived_arousal", "unsure", "foot_skate",
    "foot_skate_ratio", "path_deviation", "path_deviation_max", "heading_deviation", "frames",
    "fps", "seconds", "model", "bvh", "glb",
)


def schema() -> Any:
    """The manifest's :class:`pyarrow.Schema`."""
    types = {**dict.fromkeys(_INT, pa.int64()), **dict.fromkeys(_FLOAT, pa.float64()),
             **dict.fromkeys(_TEXT, pa.string()), "unsure": pa.bool_(),
             "emotion": pa.list_(pa.float32(), len(LABELS)),
             "emotion_end": pa.list_(pa.float32(), len(LABELS))}
    return pa.schema([(name, types[name]) for name in COLUMNS])


def table(rows: Sequence[dict[str, Any]], recipe: dict[str, Any]) -> Any:
    """The manifest of ``rows`` (any order; sorted by ``sample_id``) as a pyarrow table."""
    rows = sorted(rows, key=lambda r: r["sample_id"])
    columns = {name: [r.get(name) for r in rows] for name in COLUMNS}
    meta = {"emotive.recipe": json.dumps(recipe, sort_keys=True),
            "emotive.labels": json.dumps(list(LABELS))}
    return pa.Table.from_pydict(columns, schema=schema().with_metadata(meta))


def write_manifest(manifest: Any, path: Any) -> None:
    """Write the table to ``path`` atomically (Parquet, zstd)."""
    with atomic_output(path) as tmp:
        pq.write_table(manifest, tmp, compression="zstd")
