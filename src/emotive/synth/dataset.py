"""``SyntheticGaits``: a synthetic data set folder as a ``torch.utils.data.Dataset``.

Reads what ``emotive synth`` wrote (the main paper's augmented data set, Bhattacharya et al.
2020, section 5.2): the manifest for the rows, the shards for the arrays
(:mod:`emotive.synth.shards`). Shards are read whole on first use and the last few kept
(:data:`CACHED_SHARDS`), so reading in sample order touches each shard once.

Example::

    walks = SyntheticGaits("synthetic")
    item = walks[0]                 # {"rotations": (T, J, 4), "root": (T, 3), ...}
    loader = torch.utils.data.DataLoader(walks, batch_size=32, shuffle=True)
    motion = walks.motion(0)        # an emotive Motion, e.g. for write_bvh

Legend: ``T`` frames, ``J`` joints, ``E`` end sites, ``C`` labels, ``P`` path points.
"""

from __future__ import annotations

import json
import os
from collections import OrderedDict
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import torch
from torch.utils.data import Dataset

from emotive.core.motion import Motion
from emotive.synth.recipe import SynthError
from emotive.synth.shards import shard_name, skeleton_from_dict, walk_digest

#: Shards kept in memory.
CACHED_SHARDS = 2
#: The arrays an item holds by default (the same shape for every walk of a data set, so the
#: default collation of a ``DataLoader`` batches them).
FIELDS = ("rotations", "root", "world", "emotion", "valence_arousal")
#: Every array an item can hold (``path`` is ``(P, 2)``, a different ``P`` per trajectory).
ALL_FIELDS = (*FIELDS, "path")


class SyntheticGaits(Dataset):
    """The walks of a synthetic data set folder.

    Args:
        root: the folder ``emotive synth --out`` wrote (with ``manifest.parquet``).
        fields: the arrays of each item, among :data:`ALL_FIELDS` (default :data:`FIELDS`).

    Attributes:
        root: the folder.
        manifest: the manifest, a :class:`pyarrow.Table` (``.to_pandas()`` for pandas).
        labels: the ``C`` labels of ``emotion``.

    Each item is a dict of float32 tensors: ``rotations`` ``(T, J, 4)`` local rotations
    ``(w, x, y, z)``, ``root`` ``(T, 3)`` the root's position (metres, Y up), ``world``
    ``(T, J + E, 3)`` world positions of joints then end sites, ``emotion`` ``(T, C)``,
    ``valence_arousal`` ``(T, 2)``, ``path`` ``(P, 2)`` (``(0, 2)`` for none), and
    ``sample_id``, a 0-d int64 tensor.

    Raises:
        SynthError: the folder has no manifest (an unfinished run: run the command again), or
            an unknown field.
    """

    def __init__(self, root: str | os.PathLike, fields: tuple[str, ...] = FIELDS) -> None:
        self.root = Path(root)
        path = self.root / "manifest.parquet"
        if not path.is_file():
            raise SynthError(f"{self.root}: no manifest.parquet; give a folder `emotive synth "
                             "--out` finished (run it again to finish an interrupted one)")
        unknown = sorted(set(fields) - set(ALL_FIELDS))
        if unknown:
            raise SynthError(f"fields {', '.join(unknown)}: choose among "
                             f"{', '.join(ALL_FIELDS)}")
        self.fields = tuple(fields)
        self.manifest = pq.read_table(path)
        meta = self.manifest.schema.metadata or {}
        self.labels = tuple(json.loads(meta.get(b"emotive.labels", b"[]")))
        self._shard = self.manifest.column("shard").to_numpy()
        self._sample = self.manifest.column("sample_id").to_numpy()
        self._cache: OrderedDict[int, dict[str, np.ndarray]] = OrderedDict()

    def __len__(self) -> int:
        return self.manifest.num_rows

    def _arrays(self, shard: int) -> dict[str, np.ndarray]:
        if shard in self._cache:
            self._cache.move_to_end(shard)
            return self._cache[shard]
        with np.load(self.root / shard_name(shard), allow_pickle=False) as data:
            arrays = {key: data[key] for key in data.files}
        arrays["_row"] = {int(s): k for k, s in enumerate(arrays["sample_id"])}
        self._cache[shard] = arrays
        while len(self._cache) > CACHED_SHARDS:
            self._cache.popitem(last=False)
        return arrays

    def _locate(self, index: int) -> tuple[dict[str, Any], int]:
        if not -len(self) <= index < len(self):
            raise IndexError(f"walk {index} of {len(self)}")
        index %= len(self)
        arrays = self._arrays(int(self._shard[index]))
        return arrays, arrays["_row"][int(self._sample[index])]

    @staticmethod
    def _path(arrays: dict[str, Any], k: int) -> np.ndarray:
        p = int(arrays["path_index"][k])
        if p < 0:
            return np.zeros((0, 2), np.float32)
        lo, hi = arrays["path_offsets"][p], arrays["path_offsets"][p + 1]
        return arrays["path_points"][lo:hi]

    def __getitem__(self, index: int) -> dict[str, torch.Tensor]:
        arrays, k = self._locate(index)
        out = {"sample_id": torch.tensor(int(arrays["sample_id"][k]))}
        for name in self.fields:
            value = self._path(arrays, k) if name == "path" else arrays[name][k]
            out[name] = torch.from_numpy(np.array(value, dtype=np.float32))
        return out

    def row(self, index: int) -> dict[str, Any]:
        """The manifest row of walk ``index``."""
        return {name: self.manifest.column(name)[index].as_py()
                for name in self.manifest.column_names}

    def motion(self, index: int) -> Motion:
        """Walk ``index`` as a :class:`~emotive.core.motion.Motion` (float32 values)."""
        arrays, k = self._locate(index)
        skeleton = skeleton_from_dict(json.loads(str(arrays["skeleton"])))
        rotations = arrays["rotations"][k].astype(np.float64)
        positions = np.repeat(arrays["translations"][None], len(rotations), 0)
        positions[:, int(arrays["root_joint"])] = arrays["root"][k]
        return Motion(skeleton, rotations, positions, float(arrays["fps"]),
                      {"name": f"walk-{int(arrays['sample_id'][k]):06d}"})

    def verify(self, index: int) -> bool:
        """Whether walk ``index``'s arrays still hash to the manifest's ``sha256``."""
        arrays, k = self._locate(index)
        walk = {name: arrays[name][k] for name in FIELDS}
        path = self._path(arrays, k)
        if len(path):
            walk["path"] = path
        return walk_digest(walk) == self.manifest.column("sha256")[index].as_py()
