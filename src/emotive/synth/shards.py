"""One shard of a synthetic data set: its walks made in one batch, measured, hashed, packed.

A shard is the fixed index range of :meth:`Recipe.shard_range
<emotive.synth.recipe.Recipe.shard_range>`; :func:`make_shard` makes its walks with one
batched call of the recipe's walker (:mod:`emotive.synth.walkers`), on one torch thread, and
returns the bytes of its files, so that it can run in any process of any machine (a Ray
worker, :mod:`emotive.synth.engine`) and the process that owns the folder writes them.
Everything a walk is depends on the recipe and its sample index (and the shard that batches
it, which the recipe fixes), so the bytes are the same wherever the shard is made.

Shard file ``shards/shard-NNNNN.npz`` (NumPy, uncompressed, its bytes a function of its arrays
alone, :func:`npz_bytes`; ``n`` walks, ``T`` frames):

* ``sample_id`` ``(n,)``; ``rotations`` ``(n, T, J, 4)`` float32 local rotations
  ``(w, x, y, z)``; ``root`` ``(n, T, 3)`` float32 local translation of ``root_joint`` (the
  root's world position, metres, Y up); ``world`` ``(n, T, J + E, 3)`` float32 world
  positions of joints then end sites; ``emotion`` ``(n, T, C)`` float32 weights over
  ``labels``; ``valence_arousal`` ``(n, T, 2)`` float32, -1..1;
* ``path_index`` ``(n,)`` index of each walk's path among the shard's ``path_offsets``
  ``(u + 1,)`` into ``path_points`` ``(P, 2)`` float32 ``(x, z)`` (``-1``: no path);
* the rig: ``skeleton`` (JSON: names, parents, offsets, channels, end sites), ``translations``
  ``(J, 3)`` the local translations of every joint but the root (constant), ``root_joint``;
  ``fps``; ``labels`` ``(C,)``;
* ``rows`` (JSON: the walks' manifest rows) and ``recipe_id``.

A walk's ``sha256`` is that of its arrays' float32 bytes (rotations, root, world, emotion,
valence/arousal, path points), each preceded by its name and shape (:func:`walk_digest`).

Per-walk files (``--formats bvh,glb``): ``bvh/walk-NNNNNN.bvh``, ``glb/walk-NNNNNN.glb``.

Legend: ``n`` walks, ``T`` frames, ``J`` joints, ``E`` end sites, ``C`` labels, ``u`` paths.
"""

from __future__ import annotations

import functools
import hashlib
import io
import json
import tempfile
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from emotive.core.motion import Motion
from emotive.core.roles import resolve_roles
from emotive.core.skeleton import Skeleton
from emotive.io.motion_files import write_motion
from emotive.paths import GroundPath
from emotive.retarget import retarget
from emotive.synth import emotions as emo
from emotive.synth.emotions import LABELS
from emotive.synth.measures import measure
from emotive.synth.recipe import Recipe, SampleSpec, recipe_id
from emotive.synth.trajectories import Trajectory, trajectory
from emotive.synth.walkers import WalkBatch, load_walker

#: Seed stream of each walk's own seed (the second entry of its generator's seed).
WALK_STREAM = 5
#: The shards' folder inside a data set folder.
SHARDS = "shards"


def shard_name(shard: int) -> str:
    """Relative path of shard ``shard``'s file."""
    return f"{SHARDS}/shard-{shard:05d}.npz"


def walk_name(sample: int, fmt: str) -> str:
    """Relative path of sample ``sample``'s file of format ``fmt`` (``bvh``, ``glb``)."""
    return f"{fmt}/walk-{sample:06d}.{fmt}"


@dataclass(frozen=True)
class ShardResult:
    """What :func:`make_shard` returns.

    Attributes:
        shard: the shard index.
        files: relative path -> bytes, the shard file last.
        rows: the walks' manifest rows.
    """

    shard: int
    files: dict[str, bytes]
    rows: list[dict[str, Any]]


def walk_seed(seed: int, sample: int) -> int:
    """The seed of sample ``sample``'s own random choices (its stepping phase, its noise)."""
    return int(np.random.default_rng([seed, WALK_STREAM, sample]).integers(0, 2**31 - 1))


@functools.cache
def _trajectory(seed: int, path: int, seconds: float, draw: int) -> Trajectory:
    return trajectory(seed, path, seconds, draw)


@functools.cache
def _emotion(seed: int, index: int, point: bool) -> emo.NovelEmotion:
    return emo.novel_emotion(seed, index, point)


@functools.cache
def _pairs(seed: int, path: int, emotions: int, count: int) -> np.ndarray:
    return emo.pairs(seed, path, emotions, count)


@functools.cache
def _walker(model: str) -> Any:
    return load_walker(model)


def plan(recipe: Recipe, spec: SampleSpec, point: bool, draws: Sequence[int]
         ) -> dict[str, Any]:
    """Sample ``spec``'s trajectory, emotions, keyframes and manifest entries of its recipe.

    ``draws`` ``(P,)`` gives the draw of each trajectory
    (:func:`emotive.synth.novelty.novel_trajectories`).
    """
    seed = recipe.seed
    if spec.pair is None:
        first, second, start, ramp = _emotion(seed, spec.emotion, point), None, np.nan, np.nan
    else:
        a, b = _pairs(seed, spec.path, recipe.emotions, recipe.transitions)[spec.pair]
        first, second = _emotion(seed, int(a), point), _emotion(seed, int(b), point)
        start, ramp = emo.switch_time(seed, spec.index, recipe.seconds)
    keyframes = emo.schedule_keyframes(first, second, start, ramp)
    return {
        "trajectory": _trajectory(seed, spec.path, recipe.seconds, int(draws[spec.path])),
        "keyframes": keyframes,
        "row": {
            "sample_id": spec.index, "kind": "transition" if second else "constant",
            "path_id": spec.path, "emotion_id": -1 if second else first.index,
            "transition_from": first.index if second else -1,
            "transition_to": second.index if second else -1,
            "transition_time": start, "transition_seconds": ramp,
            "seed": seed, "walk_seed": walk_seed(seed, spec.index),
        },
    }


def walk_digest(arrays: dict[str, np.ndarray]) -> str:
    """sha256 of a walk's arrays: each one's name, shape and float32 bytes, in the given order."""
    h = hashlib.sha256()
    for name, value in arrays.items():
        value = np.ascontiguousarray(value, dtype=np.float32)
        h.update(f"{name}{value.shape}".encode())
        h.update(value.tobytes())
    return h.hexdigest()


def make_shard(values: dict[str, Any], rig: Motion | None, draws: Sequence[int], shard: int
               ) -> ShardResult:
    """Make, measure and pack the walks of shard ``shard`` (module docstring).

    Args:
        values: the recipe (:meth:`Recipe.to_dict
            <emotive.synth.recipe.Recipe.to_dict>`, with its extra entries).
        rig: the ``--rig`` clip to retarget every walk onto, or ``None``.
        draws: ``(P,)`` the draw of each trajectory (the folder's ``novelty.json``).
        shard: the shard index.

    Returns:
        The shard's files and rows.
    """
    torch.set_num_threads(1)
    recipe = Recipe.from_dict(values)
    walker = _walker(recipe.model)
    specs = [recipe.sample(i) for i in recipe.shard_range(shard)]
    plans = [plan(recipe, spec, walker.point, draws) for spec in specs]
    batch = walker.walk([p["trajectory"].path for p in plans], [p["keyframes"] for p in plans],
                        [p["row"]["walk_seed"] for p in plans], recipe.seconds)
    motions = [batch.motion(k, f"walk-{spec.index:06d}") for k, spec in enumerate(specs)]
    paths = list(batch.paths)
    if rig is not None:
        motions, paths = _on_rig(motions, paths, rig, recipe.rig_roles)
    return _pack(recipe, values, shard, batch, motions, paths, plans)


def _on_rig(motions: list[Motion], paths: list, rig: Motion, roles: str | None
            ) -> tuple[list[Motion], list]:
    """Every walk retargeted onto ``rig``, its path scaled as its root motion."""
    out_m, out_p = [], []
    for motion, path in zip(motions, paths, strict=True):
        moved = retarget(motion, rig, target_roles=roles)
        out_m.append(moved.replace(metadata={**moved.metadata, "name": motion.metadata["name"]}))
        out_p.append(None if path is None else GroundPath.from_polyline(
            path.points * moved.metadata["leg_scale"], path.closed, path.name))
    return out_m, out_p


def _pack(recipe: Recipe, values: dict, shard: int, batch: WalkBatch, motions: list[Motion],
          paths: list, plans: list[dict]) -> ShardResult:
    """Measure every walk, hash it and pack the shard's files."""
    skeleton, fps = motions[0].skeleton, motions[0].fps
    role_map = recipe.rig_roles if recipe.rig else None
    rotations = np.stack([m.rotations for m in motions])
    positions = np.stack([m.positions for m in motions])
    n, t = rotations.shape[:2]
    # One forward kinematics for the whole shard: (N T) frames of one clip.
    world = Motion(skeleton, rotations.reshape(n * t, *rotations.shape[2:]),
                   positions.reshape(n * t, *positions.shape[2:]), fps
                   ).positions_with_end_sites().reshape(n, t, -1, 3)
    root_joint, translations = _split_translations(positions)
    arrays = {
        "rotations": rotations.astype(np.float32),
        "root": positions[:, :, root_joint].astype(np.float32),
        "world": world.astype(np.float32),
        "emotion": batch.emotion.astype(np.float32),
        "valence_arousal": batch.valence_arousal.astype(np.float32),
    }
    measures = measure(skeleton, resolve_roles(skeleton, role_map),
                       arrays["world"].astype(np.float64), fps, paths)
    unique: dict[bytes, int] = {}
    path_points, path_index = [], []
    for path in paths:
        if path is None:
            path_index.append(-1)
            continue
        pts = np.asarray(path.points, dtype=np.float32)
        key = pts.tobytes()
        if key not in unique:
            unique[key] = len(path_points)
            path_points.append(pts)
        path_index.append(unique[key])
    files: dict[str, bytes] = {}
    rows = []
    for k, (motion, p) in enumerate(zip(motions, plans, strict=True)):
        walk = {name: value[k] for name, value in arrays.items()}
        if path_index[k] >= 0:
            walk["path"] = path_points[path_index[k]]
        row = {**p["row"], "shard": shard, **_emotion_columns(arrays, k),
               "frames": motion.num_frames, "fps": motion.fps, "seconds": recipe.seconds,
               "model": recipe.model, "sha256": walk_digest(walk), **measures[k]}
        for fmt in recipe.formats[1:]:
            name = walk_name(row["sample_id"], fmt)
            files[name] = _motion_bytes(motion, fmt)
            row[fmt] = name
        rows.append(row)
    offsets = np.cumsum([0] + [len(p) for p in path_points])
    payload = {
        "sample_id": np.array([r["sample_id"] for r in rows], dtype=np.int64), **arrays,
        "path_index": np.array(path_index, dtype=np.int64),
        "path_offsets": offsets.astype(np.int64),
        "path_points": (np.concatenate(path_points) if path_points
                        else np.zeros((0, 2), np.float32)),
        "skeleton": np.array(json.dumps(skeleton_dict(skeleton))),
        "translations": translations, "root_joint": np.int64(root_joint),
        "fps": np.float64(fps), "labels": np.array(LABELS),
        "rows": np.array(json.dumps(rows)), "recipe_id": np.array(recipe_id(values)),
    }
    files[shard_name(shard)] = npz_bytes(payload)
    return ShardResult(shard, files, rows)


def npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    """The bytes of an uncompressed ``.npz`` of ``arrays`` that depend on the arrays alone.

    :func:`numpy.savez` stamps each member with the time it was written; here every member
    has the same fixed time, so the same arrays give the same file.
    """
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_STORED) as archive:
        for name, value in arrays.items():
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            with archive.open(info, "w", force_zip64=True) as fh:
                np.lib.format.write_array(fh, np.asanyarray(value), allow_pickle=False)
    return buffer.getvalue()


def _emotion_columns(arrays: dict[str, np.ndarray], k: int) -> dict[str, Any]:
    """The walk's emotion and valence/arousal at its first and last frame."""
    e, va = arrays["emotion"][k], arrays["valence_arousal"][k]
    return {"emotion": [float(x) for x in e[0]], "emotion_end": [float(x) for x in e[-1]],
            "valence": float(va[0, 0]), "arousal": float(va[0, 1]),
            "valence_end": float(va[-1, 0]), "arousal_end": float(va[-1, 1])}


def _split_translations(positions: np.ndarray) -> tuple[int, np.ndarray]:
    """The root joint (the one joint whose translation moves) and the others' ``(J, 3)``.

    Raises:
        ValueError: more than one joint's translation moves (no rig of the toolkit does).
    """
    rest = positions[0, 0]
    moving = np.flatnonzero(~np.all(positions == rest, axis=(0, 1, 3)))
    if len(moving) > 1:
        raise ValueError(f"joints {moving.tolist()} all move: a shard holds one root joint")
    return (int(moving[0]) if len(moving) else 0), rest.astype(np.float64)


def skeleton_dict(skeleton: Skeleton) -> dict[str, Any]:
    """A skeleton as JSON-able values (floats round-trip exactly)."""
    return {"names": list(skeleton.names), "parents": skeleton.parents.tolist(),
            "offsets": skeleton.offsets.tolist(), "channels": [list(c) for c in skeleton.channels],
            "end_site_parents": skeleton.end_site_parents.tolist(),
            "end_site_offsets": skeleton.end_site_offsets.tolist()}


def skeleton_from_dict(values: dict[str, Any]) -> Skeleton:
    """The skeleton of :func:`skeleton_dict`'s output."""
    return Skeleton(tuple(values["names"]), np.array(values["parents"], dtype=np.int64),
                    np.array(values["offsets"], dtype=np.float64),
                    tuple(tuple(c) for c in values["channels"]),
                    np.array(values["end_site_parents"], dtype=np.int64),
                    np.array(values["end_site_offsets"], dtype=np.float64).reshape(-1, 3))


def _motion_bytes(motion: Motion, fmt: str) -> bytes:
    """The bytes of ``motion`` written as ``fmt`` (``bvh`` or ``glb``)."""
    with tempfile.TemporaryDirectory(prefix="emotive-synth-") as folder:
        path = Path(folder) / f"walk.{fmt}"
        write_motion(motion, path)
        return path.read_bytes()
