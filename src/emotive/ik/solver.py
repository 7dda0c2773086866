"""Damped least squares IK on one chain, batched over frames and warm-started in time.

Frames are cut into segments solved side by side: within a segment each frame starts from the
previous frame's solution, so the Python loop runs over a segment's length, not the clip's.
Each segment but the first starts ``burn_in`` frames early from the initial pose and discards
those frames, so that its first kept frame is already warm.

Frames that end more than ``retry_above`` from a target are solved again, and the best of three
retries is kept: from their own solution with ``retry_iter`` iterations, from the initial pose
with as many, and backwards in time from the next frame on target over at most
:data:`RETRY_BACKWARD` frames (a warm start that the forward pass, stuck in the wrong branch
after a joint limit, could not give them). Frames still
more than ``off_target`` away are reported in :attr:`ChainSolution.off_target`: on the Bandai
Namco clips more iterations alone do not help them (the poses leave the joint limits or the
solver sits in a local minimum), so they are reported instead of silently kept.

Legend: ``T`` frames, ``B`` segments solved together, ``k`` chain joints, ``M`` targets.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import torch

from emotive.ik.chains import Chain, IKError, theta_from_rotations
from emotive.transforms.kinematics import forward_kinematics
from emotive.transforms.np_rotations import quaternion_apply as np_quaternion_apply
from emotive.transforms.rotations import (
    axis_angle_to_quaternion,
    quaternion_apply,
    quaternion_multiply,
    quaternion_to_matrix,
)

_DTYPE = torch.float64
#: Residual above which a frame is retried and reported as off target, metres. The solver's
#: tolerance is 0.2 mm; 10 mm is a visible miss.
OFF_TARGET = 0.01
#: Most frames of a run off target that the backward retry walks through (it steps through
#: them one by one, so a long run would cost a long sequential pass).
RETRY_BACKWARD = 60


@dataclass(frozen=True)
class Unreachable:
    """Targets beyond a chain's reach, clamped onto it before solving.

    Attributes:
        frames: ``(N,)`` frame of each clamped target.
        targets: ``(N,)`` role of each clamped target.
        distances: ``(N,)`` how far beyond the reach the target was, metres.
    """

    frames: np.ndarray
    targets: tuple[str, ...]
    distances: np.ndarray

    def __len__(self) -> int:
        return len(self.frames)


@dataclass(frozen=True)
class ChainSolution:
    """Result of :func:`solve_chain`.

    Attributes:
        rotations: ``(T, k, 4)`` local rotations of the chain joints.
        theta: ``(T, k, 3)`` chain parameters (inside the limits).
        residual: ``(T,)`` largest distance between a (clamped) target and its point, metres.
        iterations: ``(T,)`` DLS iterations spent on each frame (retries included).
        unreachable: the clamped targets.
        off_target: ``(K,)`` frames whose residual stays above the ``off_target`` tolerance
            after the retries.
    """

    rotations: np.ndarray
    theta: np.ndarray
    residual: np.ndarray
    iterations: np.ndarray
    unreachable: Unreachable
    off_target: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))


def check_targets(name: str, targets: np.ndarray) -> None:
    """Raise :class:`IKError` naming the chain and frames when targets hold NaN or inf."""
    bad = ~np.isfinite(targets).reshape(len(targets), -1).all(-1)
    if bad.any():
        frames = np.flatnonzero(bad)
        shown = ", ".join(str(f) for f in frames[:10]) + (" ..." if len(frames) > 10 else "")
        raise IKError(
            f"chain {name}: targets are NaN or infinite at {len(frames)} frame(s) [{shown}]; "
            "fill or interpolate the trajectory before solving"
        )


def clamp_to_reach(
    chain: Chain, origin: np.ndarray, targets: np.ndarray, slack: float = 1e-6
) -> tuple[np.ndarray, Unreachable]:
    """Pull targets beyond reach back onto the sphere the chain can reach.

    Args:
        chain: the chain.
        origin: ``(T, 3)`` world position of the chain's first joint.
        targets: ``(T, M, 3)`` world targets.
        slack: distances within ``reach + slack`` count as reachable.

    Returns:
        The clamped ``(T, M, 3)`` targets and the report.
    """
    d = targets - origin[:, None]
    dist = np.linalg.norm(d, axis=-1)
    over = dist > chain.reach + slack
    scale = np.where(over, chain.reach / np.where(over, dist, 1.0), 1.0)
    frames, which = np.nonzero(over)
    report = Unreachable(
        frames, tuple(chain.target_roles[m] for m in which), (dist - chain.reach)[frames, which]
    )
    return origin[:, None] + d * scale[..., None], report


@contextmanager
def single_thread() -> Iterator[None]:
    """Run torch on one thread inside the block, restoring the setting after.

    The IK tensors are small: thread hand-offs cost more than the arithmetic, and on a shared
    machine they can slow each call by two orders of magnitude.
    """
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


def _right_jacobian(v: torch.Tensor) -> torch.Tensor:
    """``(..., 3, 3)`` right Jacobian of the exponential map at rotation vectors ``v``."""
    angle = v.norm(dim=-1, keepdim=True)[..., None]
    small = angle < 1e-6
    a = torch.where(small, torch.ones_like(angle), angle)
    c1 = torch.where(small, 0.5 - angle**2 / 24, (1 - torch.cos(a)) / a**2)
    c2 = torch.where(small, 1 / 6 - angle**2 / 120, (a - torch.sin(a)) / a**3)
    x, y, z = v.unbind(-1)
    zero = torch.zeros_like(x)
    skew = torch.stack((zero, -z, y, z, zero, -x, -y, x, zero), -1).reshape(*v.shape, 3)
    eye = torch.eye(3, dtype=v.dtype)
    return eye - c1 * skew + c2 * (skew @ skew)


class _ChainKernel:
    """Forward kinematics and Jacobian of one chain for a batch of frames."""

    def __init__(self, chain: Chain) -> None:
        k, m = len(chain.joints), len(chain.targets)
        self.k, self.m = k, m
        self.ref = torch.as_tensor(chain.ref, dtype=_DTYPE)
        self.axes = torch.as_tensor(chain.axes, dtype=_DTYPE)
        self.lower = torch.as_tensor(chain.lower, dtype=_DTYPE)
        self.upper = torch.as_tensor(chain.upper, dtype=_DTYPE)
        self.active = (self.upper > self.lower).to(_DTYPE).reshape(-1)
        self.sqrt_w = torch.as_tensor(np.sqrt(chain.weights), dtype=_DTYPE)
        # Node 0 is the base, nodes 1..k the chain joints, then one node per target.
        self.parents = [-1, *range(k), *(int(a) + 1 for a in chain.anchors)]
        dep = np.arange(k)[None, :] <= chain.anchors[:, None]
        self.anchors = torch.as_tensor(chain.anchors)
        self.dep = torch.as_tensor(dep, dtype=_DTYPE)[:, :, None, None]

    def local(self, theta: torch.Tensor) -> torch.Tensor:
        v = (self.axes @ theta[..., None])[..., 0]
        ref = self.ref.expand(*theta.shape[:-1], 4)
        return quaternion_multiply(ref, axis_angle_to_quaternion(v))

    def points(
        self, theta: torch.Tensor, base_rot: torch.Tensor, nodes_pos: torch.Tensor,
        link: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """World rotations ``(B, k, 4)``, joint positions ``(B, k, 3)``, targets ``(B, M, 3)``.

        The same transforms as :func:`forward_kinematics` on the chain's nodes, written as the
        serial product it is: the generic level-by-level gathers cost more than the arithmetic
        on tensors this small, and this runs in the innermost loop. ``link`` (``(B, k, 4)``,
        or ``None`` for the identity) turns each joint's parent frame (the intermediates of
        :func:`~emotive.ik.chains.link_transforms`).
        """
        local = self.local(theta)
        if link is not None:
            local = quaternion_multiply(link, local)
        rot, pos = base_rot, nodes_pos[:, 0]
        rots, poss = [], []
        for i in range(self.k):
            pos = pos + quaternion_apply(rot, nodes_pos[:, i + 1])
            rot = quaternion_multiply(rot, local[:, i])
            rots.append(rot)
            poss.append(pos)
        grot, jpos = torch.stack(rots, 1), torch.stack(poss, 1)
        anchors = self.anchors
        pts = jpos[:, anchors] + quaternion_apply(grot[:, anchors], nodes_pos[:, self.k + 1 :])
        return grot, jpos, pts

    def points_reference(
        self, theta: torch.Tensor, base_rot: torch.Tensor, nodes_pos: torch.Tensor,
        link: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """:meth:`points` by :func:`forward_kinematics` (the check that both agree)."""
        b = theta.shape[0]
        ident = torch.zeros(b, self.m, 4, dtype=_DTYPE)
        ident[..., 0] = 1.0
        local = self.local(theta)
        if link is not None:
            local = quaternion_multiply(link, local)
        rots = torch.cat((base_rot[:, None], local, ident), 1)
        grot, gpos = forward_kinematics(rots, nodes_pos, self.parents)
        k = self.k
        return grot[:, 1 : k + 1], gpos[:, 1 : k + 1], gpos[:, k + 1 :]

    def jacobian(
        self, theta: torch.Tensor, grot: torch.Tensor, jpos: torch.Tensor, pts: torch.Tensor
    ) -> torch.Tensor:
        """``(B, 3M, 3k)`` derivative of the target points with respect to ``theta``."""
        v = (self.axes @ theta[..., None])[..., 0]
        # World direction of each parameter axis: a step d theta rotates joint i by
        # exp(J_r(v) A d theta) in its own frame.
        world_axes = quaternion_to_matrix(grot) @ _right_jacobian(v) @ self.axes  # (B,k,3,3)
        lever = pts[:, :, None, :] - jpos[:, None, :, :]  # (B,M,k,3)
        cols = torch.linalg.cross(
            world_axes.transpose(-1, -2)[:, None], lever[:, :, :, None, :].expand(
                -1, -1, -1, 3, -1
            ),
        )  # (B,M,k,3 params,3 xyz)
        cols = cols * self.dep
        b = theta.shape[0]
        jac = cols.permute(0, 1, 4, 2, 3).reshape(b, 3 * self.m, 3 * self.k)
        return jac * self.active


def solve_chain(
    chain: Chain,
    base_rot: np.ndarray,
    base_pos: np.ndarray,
    local_pos: np.ndarray,
    target_offsets: np.ndarray,
    targets: np.ndarray,
    init: np.ndarray,
    *,
    link_rot: np.ndarray | None = None,
    posture: np.ndarray | None = None,
    damping: float = 0.01,
    posture_gain: float = 0.2,
    max_iter: int = 12,
    tol: float = 2e-4,
    warm_start: bool = True,
    segment: int = 32,
    burn_in: int = 8,
    retry_above: float = OFF_TARGET,
    retry_iter: int = 24,
    off_target: float = OFF_TARGET,
) -> ChainSolution:
    """Solve one chain for every frame by damped least squares with joint limits.

    Each iteration takes the step ``H^-1 J'e + g (I - H^-1 J'J) (posture - theta)`` with
    ``H = J'J + l^2 I`` (``l`` damping, ``g`` posture gain: the second term pulls redundant DOF,
    such as the knee's swivel, to the posture in the task's null space instead of letting
    them drift), caps it at 0.5 rad per joint, and clamps ``theta`` to the limits.

    Args:
        chain: the chain.
        base_rot: ``(T, 4)`` world rotation of the chain's base joint.
        base_pos: ``(T, 3)`` world position of the chain's base joint.
        local_pos: ``(T, k, 3)`` translation of each chain joint in the previous chain joint's
            frame (the base's for the first): the local translations, on a chain without
            intermediate joints (see :func:`~emotive.ik.chains.link_transforms`).
        target_offsets: ``(T, M, 3)`` offset of each target point in its anchor joint's frame.
        targets: ``(T, M, 3)`` world targets, metres.
        init: ``(T, k, 4)`` or ``(k, 4)`` initial local rotations (used by the first frame of
            each segment, or by every frame when ``warm_start`` is off).
        link_rot: ``(T, k, 4)`` rotation of each chain joint's parent frame in the previous
            chain joint's frame (the product of the intermediate joints' local rotations);
            ``None``: the identity (no intermediates).
        posture: ``(T, k, 4)`` or ``(k, 4)`` pose the redundant DOF lean to; ``init`` if None.
        damping: DLS damping ``l``, metres.
        posture_gain: ``g``, fraction of the posture gap closed per iteration; 0 disables it.
        max_iter: iteration cap per frame (three times that for a segment's first frame).
        tol: stop when every target is within ``tol`` metres, or the step is below 1e-7 rad.
        warm_start: start each frame from the previous frame's solution.
        segment: frames per segment solved in sequence (``warm_start`` only).
        burn_in: extra frames each segment solves before its own first frame.
        retry_above: frames whose residual exceeds this many metres are solved again (see the
            module docstring); ``inf`` disables the retries.
        retry_iter: iteration cap of the retries that solve each frame alone (three times
            that, as for every first frame); the backward retry uses ``max_iter``.
        off_target: frames whose final residual exceeds this many metres are reported.

    Returns:
        The solution.

    Raises:
        IKError: NaN or infinite targets (naming the chain and frames), or wrong shapes.
    """
    with single_thread():
        args = (chain, *(np.asarray(a, dtype=np.float64)
                         for a in (base_rot, base_pos, local_pos, target_offsets, targets)),
                None if link_rot is None else np.asarray(link_rot, dtype=np.float64))
        sol = _solve(*args, init, posture, damping, posture_gain, max_iter, tol, warm_start,
                     segment, burn_in)
        t_len = len(sol.residual)
        post = np.broadcast_to(np.asarray(init if posture is None else posture, np.float64),
                               (t_len, len(chain.joints), 4))
        sol = _retry(args, sol, post, np.broadcast_to(np.asarray(init, np.float64), post.shape),
                     damping, posture_gain, max_iter, retry_iter, tol, retry_above)
        off = np.flatnonzero(sol.residual > off_target)
        return ChainSolution(sol.rotations, sol.theta, sol.residual, sol.iterations,
                             sol.unreachable, off)


def _retry(
    args: tuple,
    sol: ChainSolution,
    posture: np.ndarray,
    init: np.ndarray,
    damping: float,
    posture_gain: float,
    max_iter: int,
    retry_iter: int,
    tol: float,
    above: float,
) -> ChainSolution:
    """Solve the frames whose residual exceeds ``above`` again; keep each frame's best.

    Args:
        args: ``(chain, base_rot, base_pos, local_pos, target_offsets, targets, link_rot)``
            of the solve.
        sol: the first solution.
        posture: ``(T, k, 4)`` posture of the solve.
        init: ``(T, k, 4)`` initial pose of the solve.
        damping: DLS damping, as in :func:`solve_chain`.
        posture_gain: posture gain, as in :func:`solve_chain`.
        max_iter: iteration cap of the backward retry.
        retry_iter: iteration cap of the retries that solve each frame alone.
        tol: target tolerance in metres, as in :func:`solve_chain`.
        above: residual in metres above which a frame is solved again.
    """
    bad = np.flatnonzero(sol.residual > above)
    if not len(bad):
        return sol
    chain, targets = args[0], args[5]
    t_len = len(targets)
    rot, theta = sol.rotations.copy(), sol.theta.copy()
    resid, iters = sol.residual.copy(), sol.iterations.copy()

    def attempt(frames: np.ndarray, start: np.ndarray, warm: bool) -> None:
        sub = _frames_of(args, frames)
        r = _solve(chain, *sub, start, posture[frames], damping, posture_gain, retry_iter, tol,
                   warm, len(frames), 0)
        iters[frames] += r.iterations
        better = r.residual < resid[frames]
        f = frames[better]
        rot[f], theta[f], resid[f] = r.rotations[better], r.theta[better], r.residual[better]

    attempt(bad, rot[bad], False)
    attempt(bad, init[bad], False)
    # Backwards from the next frame on target through each run of frames still off target, all
    # runs side by side: row r holds run r reversed after its good frame, padded with its last.
    still = np.flatnonzero(resid > above)
    runs = np.split(still, np.flatnonzero(np.diff(still) > 1) + 1) if len(still) else []
    # The backward pass is sequential: each run is retried over its last frames only.
    runs = [r[-RETRY_BACKWARD:] for r in runs if r[-1] + 1 < t_len]
    if runs:
        width = max(len(r) for r in runs) + 1
        rows = np.stack([np.pad(np.arange(r[-1] + 1, r[0] - 1, -1), (0, width - len(r) - 1),
                                mode="edge") for r in runs])
        real = np.arange(width)[None, :] <= np.array([len(r) for r in runs])[:, None]
        frames = rows.ravel()
        sub = _frames_of(args, frames)
        r = _solve(chain, *sub, rot[frames], posture[frames], damping, posture_gain,
                   max_iter, tol, True, width, 0)
        keep = real.ravel()
        f, res = frames[keep], r.residual[keep]
        iters[f] += r.iterations[keep]
        better = res < resid[f]
        g = f[better]
        rot[g] = r.rotations[keep][better]
        theta[g], resid[g] = r.theta[keep][better], res[better]
    return ChainSolution(rot, theta, resid, iters, sol.unreachable)


def _frames_of(args: tuple, frames: np.ndarray) -> list[np.ndarray | None]:
    """The per-frame arrays of a solve's ``args`` (all but the chain) at ``frames``."""
    return [None if a is None else a[frames] for a in args[1:]]


def _solve(
    chain: Chain,
    base_rot: np.ndarray,
    base_pos: np.ndarray,
    local_pos: np.ndarray,
    target_offsets: np.ndarray,
    targets: np.ndarray,
    link_rot: np.ndarray | None,
    init: np.ndarray,
    posture: np.ndarray | None,
    damping: float,
    posture_gain: float,
    max_iter: int,
    tol: float,
    warm_start: bool,
    segment: int,
    burn_in: int,
) -> ChainSolution:
    targets = np.asarray(targets, dtype=np.float64)
    t_len, k, m = len(targets), len(chain.joints), len(chain.targets)
    if targets.shape != (t_len, m, 3):
        raise IKError(
            f"chain {chain.name}: targets must have shape (T, {m}, 3), got {targets.shape}"
        )
    check_targets(chain.name, targets)
    init = np.broadcast_to(np.asarray(init, dtype=np.float64), (t_len, k, 4))
    posture = init if posture is None else np.broadcast_to(posture, (t_len, k, 4))
    theta0 = np.clip(theta_from_rotations(chain, init), chain.lower, chain.upper)
    theta_post = np.clip(theta_from_rotations(chain, posture), chain.lower, chain.upper)
    origin = base_pos + np_quaternion_apply(base_rot, local_pos[:, 0])
    targets, report = clamp_to_reach(chain, origin, targets)

    kern = _ChainKernel(chain)
    nodes_pos = torch.as_tensor(
        np.concatenate((base_pos[:, None], local_pos, target_offsets), 1), dtype=_DTYPE
    )
    t_base = torch.as_tensor(base_rot, dtype=_DTYPE)
    t_targets = torch.as_tensor(targets, dtype=_DTYPE)
    t_theta0 = torch.as_tensor(theta0, dtype=_DTYPE)
    t_post = torch.as_tensor(theta_post, dtype=_DTYPE)
    t_link = None if link_rot is None else torch.as_tensor(link_rot, dtype=_DTYPE)

    if warm_start and t_len > 0:
        seg = max(1, min(segment, t_len))
        starts = np.arange(0, t_len, seg)
        begin = np.maximum(starts - burn_in, 0)
        keep_from = starts - begin
        steps = int(seg + keep_from.max())
    else:
        begin, keep_from, steps = np.zeros(1, np.int64), np.zeros(1, np.int64), 1

    theta_out = torch.zeros(t_len, k, 3, dtype=_DTYPE)
    resid_out = torch.zeros(t_len, dtype=_DTYPE)
    iters_out = np.zeros(t_len, dtype=np.int64)
    theta = None
    lam2 = damping**2
    eye = torch.eye(3 * k, dtype=_DTYPE)
    for step in range(steps):
        if warm_start:
            frames = np.minimum(begin + step, t_len - 1)
            keep = (step >= keep_from) & (begin + step < t_len)
            keep &= begin + step < np.append(starts[1:], t_len)
        else:
            frames, keep = np.arange(t_len), np.ones(t_len, bool)
        idx = torch.as_tensor(frames)
        if theta is None:
            theta = t_theta0[idx].clone()
        tgt, post = t_targets[idx], t_post[idx]
        brot, npos = t_base[idx], nodes_pos[idx]
        link = None if t_link is None else t_link[idx]
        cap = max_iter * 3 if step == 0 else max_iter
        used = torch.zeros(len(frames), dtype=torch.int64)
        # Frames still iterating: each leaves once on target or once its step vanishes.
        act = torch.arange(len(frames))
        for _ in range(cap):
            th, ta = theta[act], tgt[act]
            grot, jpos, pts = kern.points(th, brot[act], npos[act],
                                          None if link is None else link[act])
            err = ta - pts
            going = err.norm(dim=-1).amax(-1) >= tol
            if not bool(going.all()):
                act, th, err = act[going], th[going], err[going]
                grot, jpos, pts = grot[going], jpos[going], pts[going]
                if not len(act):
                    break
            b = len(act)
            jac = kern.jacobian(th, grot, jpos, pts)
            jw = jac * kern.sqrt_w.repeat_interleave(3)[:, None]
            ew = (err * kern.sqrt_w[:, None]).reshape(b, -1)
            jtj = jw.transpose(1, 2) @ jw
            grad = (jw.transpose(1, 2) @ ew[..., None]) * kern.active[:, None]
            sol = torch.linalg.solve(jtj + lam2 * eye, torch.cat((grad, jtj), -1))
            # The posture pull goes through the (damped) null space of the task, so it moves
            # only redundant DOF and does not bias the targets.
            pull = (eye - sol[..., 1:]) @ (post[act] - th).reshape(b, -1, 1)
            delta = sol[..., 0] + posture_gain * pull[..., 0] * kern.active
            delta = delta.reshape(-1, k, 3)
            norm = delta.norm(dim=-1, keepdim=True)
            delta = delta * torch.clamp(0.5 / norm.clamp_min(1e-12), max=1.0)
            theta[act] = torch.minimum(torch.maximum(th + delta, kern.lower), kern.upper)
            used[act] += 1
            act = act[norm.amax((1, 2)) >= 1e-7]
            if not len(act):
                break
        _, _, pts = kern.points(theta, brot, npos, link)
        kept = torch.as_tensor(frames[keep])
        theta_out[kept] = theta[torch.as_tensor(keep)]
        resid_out[kept] = (tgt - pts).norm(dim=-1).max(-1).values[torch.as_tensor(keep)]
        iters_out[frames[keep]] = used.numpy()[keep]
    rotations = kern.local(theta_out).numpy()
    return ChainSolution(rotations, theta_out.numpy(), resid_out.numpy(), iters_out, report)
