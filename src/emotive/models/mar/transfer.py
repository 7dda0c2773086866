"""Online style transfer: push an input frame, get an output frame (paper sections 5 and 6).

:class:`StyleTransfer` is the streaming API. Each :meth:`~StyleTransfer.push` encodes the frame
(:mod:`~emotive.models.mar.representation`), searches the neighbours of its window in every
allowed class (:mod:`~emotive.models.mar.search`), predicts the output pose and timing with
the local mixture of autoregressive models (:mod:`~emotive.models.mar.regression`), votes the
footplants among the lower-body neighbours and decodes the pose onto the input's rig. The
output style is a weight vector over the database's styles and may change at any frame
(:meth:`~StyleTransfer.set_style`). Each output frame carries its *output time*, in input
frames: the output style's own timing, so a sad walk takes longer than its neutral input.

:func:`transfer_motion` runs a whole clip through the stream and finishes it offline: output
resampled to the input frame rate at its output times, footplant likelihoods smoothed with a
Gaussian, planted feet pinned by IK (:func:`emotive.ik.pin_feet`), and, for an input rig other
than the database's, retargeting there and back (:mod:`~emotive.models.mar.retarget`). On that
path the pins are met by the analytic two-bone solve (:func:`emotive.ik.pin_feet_two_bone`):
the output is retargeted by IK once more anyway, and the damped least squares pinning cost as
much as the rest of the transfer (on a 195-frame walk it was the larger half of the time, and
an unreachable pin could throw a leg above the hips, which the two-bone solve cannot).
After the pins, swinging feet get at least the input's clearance over the floor at the same
moment of the gait (:func:`_swing_clearance`: the outputs' swinging feet passed lower than
those of real walks in any style and grazed the floor).

Then the feet are measured against the input's. No heel or toe may go more than
:data:`~emotive.ik.floor.FLOOR_ALLOWANCE` below the input's floor (each point's 5th percentile
height over the input, :func:`emotive.ik.floor.clip_floor`): deeper feet are lifted
(:func:`emotive.ik.floor.keep_above_floor`). Foot skate is the evaluation suite's
(:func:`emotive.eval.feet.foot_skating`, contacts detected on each clip alike); where the
output's exceeds the input's, the feet are pinned once more over the contacts that measure
finds on the output as well as the voted ones (the vote can miss a foot the output plants),
and :class:`TransferResult` reports both numbers either way.

Legend: ``T`` frames, ``J`` joints, ``D`` pose dimensions, ``S`` styles, ``P`` points.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import binary_dilation, gaussian_filter1d

from emotive.core.motion import Motion
from emotive.core.ops import resample
from emotive.core.roles import resolve_roles
from emotive.data.emotion import Emotion, EmotionSchedule, coerce_blend
from emotive.errors import EmotionError
from emotive.eval.feet import foot_skating
from emotive.features.contacts import FOOT_ROLES, foot_contacts, ground_heights
from emotive.ik import IKError, pin_feet, pin_feet_two_bone
from emotive.ik.floor import clip_floor, keep_above_floor, lift_feet, spread_lifts
from emotive.models.mar.config import TransferError
from emotive.models.mar.database import MARDatabase
from emotive.models.mar.regression import METHODS, predict, standardize, track_rows
from emotive.models.mar.representation import CodecState, RigCodec, RigMappingError, check_finite
from emotive.models.mar.retarget import retarget, same_rig
from emotive.models.mar.search import PointCloudSearch

StyleSpec = str | Emotion | Mapping[str, float] | np.ndarray

#: Foot skates closer than this (m/s) count as equal: below anything visible, above the
#: rounding of the float sums.
SKATE_TOLERANCE = 1e-6
#: Frames over which a pin fades in and out (:func:`emotive.ik.pin_feet`'s ``blend``); the
#: swing clearance leaves them to the pins.
PIN_BLEND = 4


@dataclass(frozen=True)
class TransferFrame:
    """One output frame of the stream.

    Attributes:
        rotations: ``(J, 4)`` local rotations on the input's rig.
        positions: ``(J, 3)`` local translations.
        vector: ``(D,)`` the output pose vector.
        time: output time in input frames (0 at the first frame).
        advance: output frames elapsed at this frame (the timing prediction).
        root: ``(2,)`` ground position of the root, metres.
        yaw: heading of the root, radians.
        contact: ``(2,)`` likelihood that the left/right foot is planted.
        mixture: ``{"dataset/action/style": weight}`` of the classes in the mixture.
    """

    rotations: np.ndarray
    positions: np.ndarray
    vector: np.ndarray
    time: float
    advance: float
    root: np.ndarray
    yaw: float
    contact: np.ndarray
    mixture: dict[str, float]


def parse_style(style: StyleSpec, db: MARDatabase) -> np.ndarray:
    """``(S,)`` weights over :attr:`MARDatabase.styles` of a style spec.

    Args:
        style: ``"proud=0.6,angry=0.4"``, a style name, ``"valence=V,arousal=A"``, an
            :class:`Emotion`, a mapping ``{style: weight}`` or an ``(S,)`` weight array
            (:func:`~emotive.data.emotion.coerce_blend`).
        db: the database whose styles the weights are over.

    Raises:
        TransferError: unknown style names or bad weights; the message lists the known styles.
    """
    try:
        return coerce_blend(style, db.styles).weights.copy()
    except EmotionError as exc:
        raise TransferError(f"style {style!r}: {exc}") from None


class StyleTransfer:
    """The streaming style translator of one input rig.

    Args:
        db: the database.
        codec: the input rig's codec (:meth:`RigCodec.for_motion`; the stream gives it the
            database's reference rotations, :meth:`MARDatabase.codec`); its rig must be the
            database's (same joint names and hierarchy); map other rigs with
            :func:`emotive.models.mar.retarget.retarget` first, as :func:`transfer_motion` does.
        style: initial output style (see :func:`parse_style`).
        action: the input's action, if known (restricts the mixture to its classes).
        input_style: the input's style, if known.
        rho: output share of the bias (``db.config.rho`` when None).
        bias: use the bias for inputs far from the database.
        method: ``"mar"``, or a simpler local model for comparisons (see
            :data:`emotive.models.mar.regression.METHODS`).
        brute_force: exact distances to every frame instead of the search trees.
        search: a shared :class:`PointCloudSearch` of ``db`` (built when None).

    Raises:
        RigMappingError: the codec's rig is not the database's.
        TransferError: unknown action, input style or output style.
    """

    def __init__(
        self, db: MARDatabase, codec: RigCodec, style: StyleSpec = "neutral", *,
        action: str | None = None, input_style: str | None = None, rho: float | None = None,
        bias: bool = True, method: str = "mar", brute_force: bool = False,
        search: PointCloudSearch | None = None,
    ) -> None:
        if not same_rig(codec.skeleton, db.skeleton):
            raise RigMappingError(
                "the stream needs input on the database rig (joints "
                f"{', '.join(db.skeleton.names[:4])}, ...); retarget the input first "
                "(emotive.models.mar.retarget.retarget or transfer_motion)"
            )
        if method not in METHODS:
            raise TransferError(f"unknown method {method!r}; use one of {METHODS}")
        if rho is not None and not 0.0 <= rho <= 1.0:
            raise TransferError(f"rho {rho} must lie in [0, 1] (0: pure style, 1: keep content)")
        self.db, self.codec = db, db.codec(codec)
        self.search = search or PointCloudSearch(db)
        self.base = db.classes_where(action, input_style)
        self.rho, self.bias, self.method, self.brute = rho, bias, method, brute_force
        self._allowed: dict[tuple[int, ...], np.ndarray] = {}
        self.set_style(style)
        self.reset()

    def reset(self) -> None:
        """Forget the stream: the next push is a first frame."""
        self._enc: CodecState | None = None
        self._dec: CodecState | None = None
        self._window: deque[np.ndarray] = deque(maxlen=self.db.config.window)
        self._x_prev: np.ndarray | None = None
        self._y_prev: np.ndarray | None = None
        self.time = 0.0
        self.frames = 0

    def set_style(self, style: StyleSpec) -> None:
        """Change the output style from the next frame on.

        Raises:
            TransferError: unknown styles, or no allowed class has all of them.
        """
        weights = parse_style(style, self.db)
        chosen = np.flatnonzero(weights > 0)
        key = tuple(int(i) for i in chosen)
        if key not in self._allowed:
            table = self.db.output_classes()[self.base][:, chosen]
            allowed = self.base[(table >= 0).all(1)]
            if len(allowed) == 0:
                names = [self.db.styles[i] for i in chosen]
                raise TransferError(
                    f"no action of the index is recorded in all of the styles {names} among "
                    "the classes the labels allow; blend styles of one action or drop "
                    "--action/--input-style"
                )
            self._allowed[key] = allowed
        self.styles, self.style_weights = chosen, weights[chosen]

    @property
    def style(self) -> dict[str, float]:
        """The current output style ``{name: weight}``."""
        return {self.db.styles[i]: float(w)
                for i, w in zip(self.styles, self.style_weights, strict=True)}

    def push(self, rotations: np.ndarray, positions: np.ndarray) -> TransferFrame:
        """Translate one input frame.

        Args:
            rotations: ``(J, 4)`` local rotations of the input frame.
            positions: ``(J, 3)`` its local translations.

        Raises:
            TransferError: NaN or infinite values in the frame.
        """
        rotations = np.asarray(rotations, dtype=np.float64)
        positions = np.asarray(positions, dtype=np.float64)
        if not (np.isfinite(rotations).all() and np.isfinite(positions).all()):
            raise TransferError(f"input frame {self.frames} holds NaN or infinite values; "
                                "repair or drop it before pushing")
        db, cfg = self.db, self.db.config
        vector, points, enc = self.codec.encode(rotations[None], positions[None], self._enc)
        first = self._enc is None
        self._enc = enc
        if not self._window:
            self._window.extend([points[0]] * cfg.window)
        self._window.append(points[0])
        window = np.stack(self._window)
        allowed = self._allowed[tuple(int(i) for i in self.styles)]
        nb = (self.search.brute_force(window, allowed) if self.brute
              else self.search.search(window, enc.yaw, allowed))
        x_t = standardize(db, vector[0])
        x_prev = x_t if self._x_prev is None else self._x_prev
        pred = predict(db, nb, x_t, x_prev, self._y_prev, self.styles, self.style_weights,
                       rho=self.rho, bias=self.bias, method=self.method)
        self._x_prev, self._y_prev = x_t, pred.pose
        out = pred.pose * db.std + db.mean
        contact = self._footplants(nb)
        if first:
            self._dec = CodecState(enc.root.copy(), enc.yaw)
            root, yaw, advance = enc.root[[0, 2]].copy(), enc.yaw, 0.0
        else:
            advance = pred.advance
            roots, yaws, self._dec = self.codec.integrate(out[None], np.array([advance]),
                                                          self._dec)
            root, yaw = roots[0], float(yaws[0])
            self.time += advance
        rot, pos = self.codec.decode(out[None], root[None], np.array([yaw]))
        self.frames += 1
        mixture = {f"{db.groups[db.class_group[c]]}/{db.class_style[c]}": float(w)
                   for c, w in zip(nb.classes, pred.mixture, strict=True) if w > 0}
        return TransferFrame(rot[0], pos[0], out, self.time, advance, root, yaw, contact,
                             mixture)

    def _footplants(self, nb) -> np.ndarray:
        """``(2,)`` footplant likelihood from the nearest lower-body neighbours.

        ``(2,)`` footplant likelihood: inverse-distance vote of the nearest lower-body
        neighbours, on the output styles' contacts at their canonical times.
        """
        db = self.db
        frames, dist = self.search.footplants(nb)
        out_cls = db.output_classes()[db.frame_class[frames]][:, self.styles]
        tau = np.broadcast_to(db.tau[frames][:, None], out_cls.shape)
        _, _, contact = track_rows(db, out_cls, tau)
        vote = 1.0 / np.maximum(dist, 1e-9)
        return np.einsum("k,o,kof->f", vote / vote.sum(), self.style_weights, contact)


@dataclass(frozen=True)
class TransferResult:
    """Output of :func:`transfer_motion`.

    Attributes:
        motion: the translated clip on the input's rig at the input's frame rate.
        contacts: ``(T_out, 2)`` planted feet of the output (the smoothed footplant vote,
            and the contacts detected on the output where it was pinned over them too).
        frames: the raw stream output, one per input frame.
        pinned: whether the feet were pinned by IK.
        skate: foot skate of the output, m/s (:func:`emotive.eval.feet.foot_skating`, the
            evaluation suite's measure: mean horizontal speed of planted feet, contacts
            detected on the clip).
        input_skate: the same measure on the input, m/s.
    """

    motion: Motion
    contacts: np.ndarray
    frames: list[TransferFrame]
    pinned: bool
    skate: float
    input_skate: float

    def feet_summary(self) -> str:
        """One phrase: the output's foot skate beside the input's, and why when it is above.

        ``"foot skate 0.011 m/s (input 0.052 m/s)"``, with what went short added where the
        output's skate exceeds the input's or no foot was planted.
        """
        line = f"foot skate {self.skate:.3f} m/s (input {self.input_skate:.3f} m/s)"
        if not self.pinned:
            found = "" if self.contacts.any() else " (no planted feet found)"
            return f"{line}; feet not pinned{found}"
        if self.skate > self.input_skate + SKATE_TOLERANCE:
            return (f"{line}: above the input's after pinning (its feet slide where neither "
                    "the style's footplants nor the contact detection find them planted)")
        return line


def _retime(frames: list[TransferFrame], codec: RigCodec, fps: float) -> tuple[
        np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Output frames at whole output times.

    Rotations ``(T, J, 4)``, positions ``(T, J, 3)``, contact likelihoods ``(T, 2)`` and the input
    frame each comes from ``(T,)``.
    """
    times = np.array([f.time for f in frames])
    grid = np.arange(0.0, times[-1] + 1e-9, 1.0)
    vectors = np.stack([f.vector for f in frames])
    roots = np.stack([f.root for f in frames])
    yaws = np.unwrap(np.array([f.yaw for f in frames]))
    contact = np.stack([f.contact for f in frames])

    def at(values: np.ndarray) -> np.ndarray:
        flat = values.reshape(len(values), -1)
        return np.stack([np.interp(grid, times, flat[:, i]) for i in range(flat.shape[1])],
                        1).reshape(len(grid), *values.shape[1:])

    rot, pos = codec.decode(at(vectors), at(roots), at(yaws[:, None])[:, 0])
    source = np.interp(grid, times, np.arange(len(times), dtype=np.float64))
    return rot, pos, at(contact), source


def transfer_motion(
    motion: Motion,
    db: MARDatabase,
    style: StyleSpec | EmotionSchedule = "neutral",
    *,
    action: str | None = None,
    input_style: str | None = None,
    rho: float | None = None,
    role_map=None,
    pin: bool = True,
    search: PointCloudSearch | None = None,
    method: str = "mar",
    bias: bool = True,
) -> TransferResult:
    """Translate a whole clip into a style (or a schedule of styles over time).

    Args:
        motion: the input clip on any rig with the joint roles, ``T >= window`` frames.
        db: the database.
        style: the output style, or an :class:`EmotionSchedule` over :attr:`MARDatabase.styles`
            (seconds of the input).
        action: the input's action, if known.
        input_style: the input's style, if known.
        rho: output share of the bias.
        role_map: role map of the input rig.
        pin: clean the feet: pin planted feet by IK, give swinging feet the input's
            clearance and keep every foot above the input's floor (``False``: the stream's
            own poses; the skates are measured either way).
        search: a shared search of ``db``.
        method: the local model, see :class:`StyleTransfer`.
        bias: use the bias, see :class:`StyleTransfer`.

    Returns:
        The output on the input's rig at the input's frame rate.

    Raises:
        TransferError: a clip shorter than the window, NaN frames, unknown labels or styles.
        RigMappingError: the input rig lacks joint roles.
    """
    name = motion.metadata.get("name", "the input")
    check_finite(motion, name)
    need = db.config.window
    if motion.num_frames < need:
        raise TransferError(f"{name} has {motion.num_frames} frames; the style transfer needs "
                            f"at least {need} (its search window); give a longer clip")
    original_fps = motion.fps
    work = motion if motion.fps == db.config.fps else resample(motion, db.config.fps)
    foreign = not same_rig(work.skeleton, db.skeleton)
    # Fails early, naming the input, when its rig cannot be mapped onto the roles.
    RigCodec.for_motion(work, role_map, name)
    if foreign:
        work = retarget(work, db.rest_motion(), source_roles=role_map)
    codec = RigCodec.for_motion(work, None, name)
    schedule = style if isinstance(style, EmotionSchedule) else None
    first_style = schedule.weights[0] if schedule is not None else style
    if schedule is not None and tuple(schedule.labels) != db.styles:
        raise TransferError("the style schedule must be over the index's styles "
                            f"({', '.join(db.styles)})")
    stream = StyleTransfer(db, codec, first_style, action=action, input_style=input_style,
                           rho=rho, bias=bias, method=method, search=search)
    weights = schedule.sample(db.config.fps, work.num_frames) if schedule is not None else None
    frames = []
    for t in range(work.num_frames):
        if weights is not None:
            stream.set_style(weights[t])
        frames.append(stream.push(work.rotations[t], work.positions[t]))
    rot, pos, like, source = _retime(frames, stream.codec, db.config.fps)
    if db.config.contact_sigma > 0 and len(like) > 1:
        like = gaussian_filter1d(like, db.config.contact_sigma, axis=0, mode="nearest")
    contacts = like > 0.5
    label = ",".join(f"{k}={v:.3g}" for k, v in stream.style.items())
    meta = {**motion.metadata, "style": label, "source": "emotive transfer (MAR)"}
    out = Motion(work.skeleton, rot, pos, db.config.fps, meta)
    pinned = False
    if pin and contacts.any():
        out = pin_feet_two_bone(out, contacts, blend=PIN_BLEND) if foreign else pin_feet(
            out, contacts, blend=PIN_BLEND).motion
        out = _swing_clearance(out, work, source, contacts)
        pinned = True
    if foreign:
        out = retarget(out, motion if motion.fps == db.config.fps
                       else resample(motion, db.config.fps), target_roles=role_map)
        out = out.replace(metadata=meta)
    if original_fps != db.config.fps:
        out = resample(out, original_fps)
        keep = np.round(np.arange(out.num_frames) * db.config.fps / original_fps).astype(int)
        contacts = contacts[np.clip(keep, 0, len(contacts) - 1)]
    roles = resolve_roles(motion.skeleton, role_map)
    points = motion.positions_with_end_sites()
    floor = clip_floor(points, roles)
    input_skate = _skate(points, roles, motion.fps)
    if pin:
        out = keep_above_floor(out, floor, role_map)
    skate = _skate(out.positions_with_end_sites(), roles, out.fps)
    if pin and skate > input_skate + SKATE_TOLERANCE:
        out, contacts, skate = pin_detected_contacts(out, contacts, floor, role_map)
        pinned = pinned or bool(contacts.any())
    return TransferResult(out, contacts, frames, pinned, skate, input_skate)


def pin_detected_contacts(motion: Motion, contacts: np.ndarray, floor: np.ndarray,
                          role_map=None) -> tuple[Motion, np.ndarray, float]:
    """The feet pinned again over the given contacts and those detected on the clip itself.

    The style's footplants are a vote of the neighbours; where the output plants a foot the
    vote missed, that foot may slide, and the skate measure (which detects contacts on the
    clip, :func:`emotive.features.contacts.foot_contacts`) sees it. Pinning over both sets
    holds it; the feet are then kept above the floor again.

    Args:
        motion: the clip, ``T`` frames.
        contacts: ``(T, 2)`` bool, the contacts already known (left, right).
        floor: ``(2, 2)`` floor heights (:func:`emotive.ik.floor.clip_floor`).
        role_map: the clip's role map.

    Returns:
        The clip, the contacts it was pinned over ``(T, 2)`` and its foot skate (m/s).
    """
    roles = resolve_roles(motion.skeleton, role_map)
    points = motion.positions_with_end_sites()
    contacts = np.asarray(contacts, dtype=bool) | foot_contacts(points, roles, motion.fps)
    if contacts.any():
        motion = keep_above_floor(_pin_any_rig(motion, contacts, role_map), floor, role_map)
        points = motion.positions_with_end_sites()
    return motion, contacts, _skate(points, roles, motion.fps)


def _swing_clearance(out: Motion, work: Motion, source: np.ndarray,
                     contacts: np.ndarray) -> Motion:
    """Swinging feet raised to the input's height above the floor at the same gait moment.

    The pinned outputs swung their feet lower than real walks of any style: dataset 1's
    ``walk_normal_001`` into proud 0.6 + angry 0.4 and into sad swung its toes a median 3.1
    and 1.1 cm above their floor and its heels 2.8 and 2.7 cm, against 3.9-5.6 cm (toes) and
    4.6-7.5 cm (heels) in the real normal, happy, sad, angry and proud walks, so a heel or
    toe stayed within 2 cm of the floor at 1.5-2 m/s in 0.6-0.8 of the output's frames
    against 0.2-0.4 in the real walks: a foot grazing the floor. Each output frame comes from
    an input frame (``source``), so outside the output's planted runs and the pins' fades
    either side, each foot is lifted by the most that its heel or toe is nearer its floor
    than the input's same point in that frame (heights above each clip's own floor,
    :func:`emotive.features.contacts.ground_heights`), spread over a few frames
    (:func:`emotive.ik.floor.spread_lifts`) and met by the two-bone solve. The same two
    transfers then swing toes 5.3 and 4.0 cm high and heels 5.0 and 5.5 cm.

    Args:
        out: the pinned output, ``T`` frames on the database's rig.
        work: the input on the database's rig at the database's frame rate.
        source: ``(T,)`` the input frame (fractional) each output frame comes from.
        contacts: ``(T, 2)`` the output's planted feet.
    """
    idx = resolve_roles(work.skeleton).indices(FOOT_ROLES)
    clearance = ground_heights(work.positions_with_end_sites()[:, idx])
    frames = np.arange(len(clearance), dtype=np.float64)
    wanted = np.stack([np.interp(source, frames, c) for c in clearance.T], 1)
    have = ground_heights(out.positions_with_end_sites()[:, idx])
    short = np.maximum(wanted - have, 0.0).reshape(-1, 2, 2).max(-1)
    swing = ~binary_dilation(contacts, np.ones((2 * PIN_BLEND + 1, 1), dtype=bool))
    return lift_feet(out, spread_lifts(np.where(swing, short, 0.0), out.fps))


def _skate(points: np.ndarray, roles, fps: float) -> float:
    """Foot skate (m/s) of ``(T, P, 3)`` points by the evaluation suite's measure."""
    if len(points) < 2:
        return 0.0
    return float(foot_skating(points, roles, fps).mean_speed)


def _pin_any_rig(motion: Motion, contacts: np.ndarray, role_map) -> Motion:
    """Planted feet held by the two-bone solve, or by the leg chains on rigs it cannot pose."""
    try:
        return pin_feet_two_bone(motion, contacts, role_map=role_map)
    except IKError:
        return pin_feet(motion, contacts, role_map=role_map).motion
