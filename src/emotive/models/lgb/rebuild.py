"""Whole-body motion from sampled trajectories by IK, in chunks solved in worker processes.

Issue 7, section 2, step 5. The pelvis is put back in the world
(:func:`emotive.ik.integrate_pelvis`) and the five chains are solved from the targets
(:func:`emotive.ik.solve_chains`), in chunks (:func:`chunk_starts`) that can run in parallel
worker processes; each chunk but the first starts :data:`OVERLAP_FRAMES` frames early and drops
them, so that its first kept frame is warm-started. The chunks depend on the length only, not
on the number of workers, so neither does the motion.

Legend: ``T`` frames.
"""

from __future__ import annotations

import math
import multiprocessing
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from emotive.core.motion import Motion
from emotive.ik import PelvisTrajectory, Trajectories, Unreachable, integrate_pelvis, rebuild
from emotive.ik.api import IKResult
from emotive.models.lgb.bootstrap import LGBError

if TYPE_CHECKING:
    from emotive.ik import Chain

__all__ = [
    "CHUNK_FRAMES",
    "OVERLAP_FRAMES",
    "SPLIT_FRAMES",
    "chunk_starts",
    "rebuild_in_chunks",
]


#: Most frames per IK chunk (the unit of parallel work and of progress reports). The solver's
#: cost per call is mostly fixed overhead (one sequential pass over a 40-frame segment per
#: chain), so few long chunks are fastest: a clip is cut into an even number of chunks (two
#: workers share them evenly), each at most this long; clips up to :data:`SPLIT_FRAMES` frames
#: are one chunk.
CHUNK_FRAMES = 15000
#: Longest clip solved as one chunk.
SPLIT_FRAMES = 3000
#: Frames each chunk but the first solves before its own first frame and drops.
OVERLAP_FRAMES = 16


def rebuild_in_chunks(
    base: Motion,
    chains: dict[str, Chain],
    traj: Trajectories,
    *,
    workers: int = 1,
    chunk: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    role_map: Any = None,
    **solver: Any,
) -> IKResult:
    """Whole-body motion on ``base``'s rig following trajectories, solved in chunks.

    The pelvis is integrated from its path, the joints outside the chains keep ``base``'s
    rotations, and the chains are solved from their targets, in chunks (see the module
    docstring).

    Args:
        base: ``T`` frames of the rig; the joints outside the chains keep its rotations.
        chains: the IK chains on that rig.
        traj: ``T`` frames of trajectories.
        workers: worker processes solving chunks side by side (1: in this process). The
            result does not depend on it.
        chunk: frames per chunk; :func:`chunk_starts` if None.
        progress: called with ``(frames done, T)`` after each solved chunk.
        role_map: as for :func:`emotive.core.roles.resolve_roles`.
        **solver: keyword arguments of :func:`emotive.ik.solver.solve_chain`.

    Returns:
        The IK result at ``base``'s frame rate; ``seconds`` is the wall time of the solve.

    Raises:
        LGBError: ``workers`` or ``chunk`` below 1.
    """
    if workers < 1 or (chunk is not None and chunk < 1):
        raise LGBError(f"workers and chunk must be >= 1, got {workers} and {chunk}")
    began = time.perf_counter()
    n = len(traj.pelvis.height)
    pos_w, _ = integrate_pelvis(traj.pelvis)
    yaw = traj.pelvis.start_heading + np.cumsum(traj.pelvis.turn)
    starts = chunk_starts(n) if chunk is None else list(range(0, max(n, 1), chunk))
    ends = [*starts[1:], n]
    jobs = []
    for a, b in zip(starts, ends, strict=True):
        a0 = max(a - OVERLAP_FRAMES, 0)
        part = base.replace(rotations=base.rotations[a0:b], positions=base.positions[a0:b])
        jobs.append((part, chains, _slice_trajectories(traj, a0, b, pos_w[a0], yaw[a0]),
                     a - a0, role_map, solver))
    if workers == 1 or len(jobs) == 1:
        parts = []
        for job, b in zip(jobs, ends, strict=True):
            parts.append(_solve_chunk(*job))
            if progress is not None:
                progress(b, n)
    else:
        parts = _run_parallel(jobs, workers, starts, ends, n, progress)
    return _join(parts, starts, base, list(chains), time.perf_counter() - began)


def chunk_starts(frames: int) -> list[int]:
    """First frame of each IK chunk of a ``frames``-frame clip.

    One chunk up to :data:`SPLIT_FRAMES` frames, else an even number of equal chunks of at most
    :data:`CHUNK_FRAMES` frames.
    """
    if frames <= SPLIT_FRAMES:
        return [0]
    count = 2 * math.ceil(frames / (2 * CHUNK_FRAMES))
    return [round(i * frames / count) for i in range(count)]


def _slice_trajectories(
    traj: Trajectories, a: int, b: int, start: np.ndarray, heading: float
) -> Trajectories:
    """Frames ``a:b`` of ``traj``, starting at world position ``start`` facing ``heading``."""
    p = traj.pelvis
    step, turn = p.displacement[a:b].copy(), p.turn[a:b].copy()
    step[:1], turn[:1] = 0.0, 0.0
    pelvis = PelvisTrajectory(p.height[a:b], step, turn, p.tilt[a:b], np.array(start, float),
                              float(heading))
    return Trajectories(pelvis, {k: v[a:b] for k, v in traj.targets.items()})


def _solve_chunk(
    base: Motion,
    chains: dict[str, Chain],
    traj: Trajectories,
    keep: int,
    role_map: Any,
    solver: dict[str, Any],
) -> tuple:
    """Rebuild one chunk and drop its first ``keep`` frames (runs in a worker process).

    Returns:
        ``(rotations, positions, residuals, unreachable, iterations, off_target)`` of the kept
        frames, frame numbers relative to the first kept frame.
    """
    r = rebuild(base, traj, chains, role_map=role_map, **solver)
    unreachable = {}
    for name, u in r.unreachable.items():
        sel = u.frames >= keep
        unreachable[name] = Unreachable(u.frames[sel] - keep,
                                        tuple(t for t, s in zip(u.targets, sel, strict=True) if s),
                                        u.distances[sel])
    return (
        r.motion.rotations[keep:], r.motion.positions[keep:],
        {k: v[keep:] for k, v in r.residuals.items()}, unreachable,
        {k: v[keep:] for k, v in r.iterations.items()},
        {k: v[v >= keep] - keep for k, v in r.off_target.items()},
    )


def _run_parallel(
    jobs: list[tuple],
    workers: int,
    starts: list[int],
    ends: list[int],
    n: int,
    progress: Callable[[int, int], None] | None,
) -> list[tuple]:
    """Solve the chunks in ``workers`` fresh processes, in any order; results in order.

    The calling program's main module must be import-safe (``if __name__ == "__main__":``).
    """
    # Not forked from this process: a fork of a process that has run torch's thread pools can
    # hang. A fork server (where the platform has one) imports the IK once and forks clean
    # workers from it, a second or two sooner than spawning each worker.
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["emotive.models.lgb.rebuild", "emotive.ik"])
    else:
        ctx = multiprocessing.get_context("spawn")
    parts: list[tuple | None] = [None] * len(jobs)
    done = 0
    with ProcessPoolExecutor(max_workers=min(workers, len(jobs)), mp_context=ctx,
                             initializer=_worker_init) as pool:
        futures = {pool.submit(_solve_chunk, *job): i for i, job in enumerate(jobs)}
        for fut in as_completed(futures):
            i = futures[fut]
            parts[i] = fut.result()
            done += ends[i] - starts[i]
            if progress is not None:
                progress(done, n)
    return parts  # type: ignore[return-value]


def _worker_init() -> None:
    """One torch thread per worker: the workers are the parallelism."""
    torch.set_num_threads(1)


def _join(
    parts: list[tuple], starts: list[int], template: Motion, names: list[str], seconds: float
) -> IKResult:
    """One :class:`~emotive.ik.IKResult` from chunk results.

    One :class:`~emotive.ik.IKResult` from chunk results starting at ``starts``, on the rig,
    frame rate and metadata of ``template``.
    """
    rot = np.concatenate([p[0] for p in parts])
    pos = np.concatenate([p[1] for p in parts])
    return IKResult(
        template.replace(rotations=rot, positions=pos),
        {k: np.concatenate([p[2][k] for p in parts]) for k in names},
        {
            k: Unreachable(
                np.concatenate([p[3][k].frames + a for p, a in zip(parts, starts, strict=True)]),
                tuple(t for p in parts for t in p[3][k].targets),
                np.concatenate([p[3][k].distances for p in parts]),
            )
            for k in names
        },
        {k: np.concatenate([p[4][k] for p in parts]) for k in names},
        seconds,
        {k: np.concatenate([p[5][k] + a for p, a in zip(parts, starts, strict=True)])
         for k in names},
    )
