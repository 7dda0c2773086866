"""Synthetic data sets at scale: the main paper's "Synthesized Emotive Gaits" (section 5.2).

``emotive synth`` (and :func:`synthesize`) walks the registry's generators on novel
trajectories with novel emotions and transitions between pairs of them, shard by shard on Ray,
into a folder that a rerun continues and that is the same, byte for byte, for any number of
workers; :class:`SyntheticGaits` reads it back as a ``torch.utils.data.Dataset``.

Modules, by concept:

* :mod:`~emotive.synth.recipe` -- the recipe, the sample layout, the shards' index ranges.
* :mod:`~emotive.synth.trajectories` -- novel trajectories (random smooth paths with turns).
* :mod:`~emotive.synth.emotions` -- novel emotions, transition pairs and times.
* :mod:`~emotive.synth.novelty` -- the trajectories checked against the data's root paths.
* :mod:`~emotive.synth.walkers` -- one batched generator call per shard, per kind of model.
* :mod:`~emotive.synth.measures` -- the classifier's reading, foot skate, path deviation.
* :mod:`~emotive.synth.shards` -- one shard made, hashed and packed.
* :mod:`~emotive.synth.store` -- the folder: recipe, lock, finished shards, leftovers.
* :mod:`~emotive.synth.engine` -- Ray: a local instance or a cluster, progress.
* :mod:`~emotive.synth.manifest`, :mod:`~emotive.synth.card` -- ``manifest.parquet``,
  ``README.md``.
* :mod:`~emotive.synth.build` -- :func:`synthesize`, the steps in order.
* :mod:`~emotive.synth.dataset` -- :class:`SyntheticGaits`.
* :mod:`~emotive.synth.classifier_data`, :mod:`~emotive.synth.classifier_mix`,
  :mod:`~emotive.synth.classifier_stats`, :mod:`~emotive.synth.classifier_study` -- what the
  data set does for emotion recognition: the perceived-emotion classifier trained on real
  clips alone and with synthetic walks, compared on held-out real walks.

The names below are imported from their modules on first access: importing the package loads
neither torch nor Ray.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "Recipe": "recipe", "SynthError": "recipe", "named_recipe": "recipe", "synthesize": "build",
    "SynthReport": "build", "SyntheticGaits": "dataset",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS})
