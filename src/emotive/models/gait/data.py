"""Training data of the emotive gait network: per-frame inputs and next-frame targets in windows.

Legend: ``F`` frames of all clips of a split, ``N`` windows, ``B`` windows of a batch, ``T``
input frames per window, ``J`` joints, ``E`` end sites, ``C`` emotion labels, ``K`` clips.

Pipeline (:func:`load_gait_data`): the locomotion clips of each data set are filtered to the
styles among the config's labels and split by clip (:func:`emotive.data.splits.split_clips`, per
data set); :func:`build_gait_data` then computes every per-frame quantity once per clip, on the
whole clip (the movement features low-pass filter and detect foot strikes over time, so a
window cut first would see edge effects), and only then cuts windows of ``T + 1`` frames that
never cross a clip. Nothing is cached on disk beyond what :func:`~emotive.data.clips.load_clips`
caches.

Per frame and clip:

* local rotations ``q`` ``(J, 4)`` with quaternion sign continuity over the clip (consecutive
  frames in one hemisphere, so the network never sees a jump between ``q`` and ``-q``);
* the 18 affective features ``a`` from world positions of joints and end sites (hand tips and
  toes are end sites on the Bandai rig), ratios in log space (:mod:`~emotive.models.gait.affect`);
* movement inputs ``[sin theta, cos theta, omega, s_lowpass, kappa]`` and root features
  ``[h, s, delta]`` (:func:`emotive.features.movement.movement_features`);
* the emotion vector ``m``: one-hot of the clip's style over the config's labels (with
  :data:`~emotive.data.emotion.ALL_LABELS`, every Bandai style is a label of its own);
* local translations for forward kinematics in the losses.

World heading. The network predicts local rotations of every joint, the hips' included, and
the hips' rotation holds the character's world heading. The network never sees that heading:
every frame is made heading-canonical on its own, exactly as
:func:`emotive.core.ops.canonicalize_facing` would do to that single frame: a rotation about Y
and a slide on the ground put the root role over the origin facing +Z. The world heading and
the path are the path follower's business at animation time
(:mod:`emotive.models.gait.generate`), which turns the body to the path's tangent corrected
by the predicted ``delta``; the network predicts the pose in the body's own frame (lean, twist
of the hips against the facing, limbs), driven by the movement inputs (curvature among them)
and the emotion. Every feature above is unchanged by this (affective features and movement
features are invariant to yaw and ground translation), so features are computed per clip and
only rotations and translations are moved, once, when the data is built. The transform is
applied to the local frame of the *mover*, the root role joint (``Hips``), so the heading lands
in the hips' rotation the network predicts; the transforms of its ancestors (the Bandai file
root ``joint_Root``), where they move, are first folded into it
(:func:`~emotive.core.root.fold_into_root`).

Targets are the inputs shifted by one frame: a window of ``T + 1`` frames gives inputs from
frames ``0 .. T - 1`` and targets from frames ``1 .. T`` (:class:`GaitBatch`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import torch
from rich.console import Console
from rich.progress import track

from emotive.core.motion import Motion
from emotive.core.ops import heading, resample
from emotive.core.roles import resolve_roles
from emotive.core.root import fold_into_root
from emotive.core.skeleton import Skeleton
from emotive.data.clips import Clip, ClipInfo, load_clips
from emotive.data.emotion import Emotion, style_to_label
from emotive.data.splits import SPLITS, split_clips, spread
from emotive.data.windows import window_starts
from emotive.errors import DataError
from emotive.features.movement import movement_features
from emotive.models.gait.affect import gait_affective_np
from emotive.models.gait.config import GaitConfig
from emotive.models.gait.network import GaitInputs
from emotive.transforms.np_rotations import (
    quaternion_apply,
    quaternion_continuity,
    quaternion_multiply,
    yaw_quaternion,
)

#: The data sets the gait network trains on by default (locomotion only).
DEFAULT_DATASETS: tuple[str, ...] = ("bandai-namco-1", "bandai-namco-2-locomotion")
#: Floor of the feature standard deviations, so that a feature constant in the training data
#: (e.g. ``omega`` of clips without foot strikes) is centred but not blown up.
MIN_STD = 1e-3


class GaitBatch(NamedTuple):
    """``B`` windows of ``T + 1`` frames, every frame heading-canonical.

    Attributes:
        rotations: ``(B, T + 1, J, 4)`` local unit quaternions.
        positions: ``(B, T + 1, J, 3)`` local translations in metres (mover: its placement).
        affective: ``(B, T + 1, 18)`` pose affective features.
        movement: ``(B, T + 1, 5)`` ``[sin theta, cos theta, omega, s_lowpass, kappa]``.
        root: ``(B, T + 1, 3)`` ``[h, s, delta]``.
        emotion: ``(B, C)`` emotion vectors, constant over each window.
    """

    rotations: torch.Tensor
    positions: torch.Tensor
    affective: torch.Tensor
    movement: torch.Tensor
    root: torch.Tensor
    emotion: torch.Tensor

    def inputs(self) -> GaitInputs:
        """Network inputs of frames ``0 .. T - 1``: ``(B, T, ...)``, emotion ``(B, C)``."""
        return GaitInputs(
            self.rotations[:, :-1], self.affective[:, :-1], self.emotion,
            self.movement[:, :-1], self.root[:, :-1],
        )

    @property
    def next_rotations(self) -> torch.Tensor:
        """``(B, T, J, 4)`` targets: the rotations of frames ``1 .. T``."""
        return self.rotations[:, 1:]

    @property
    def next_root(self) -> torch.Tensor:
        """``(B, T, 3)`` targets: ``[h, s, delta]`` of frames ``1 .. T``."""
        return self.root[:, 1:]

    @property
    def next_positions(self) -> torch.Tensor:
        """``(B, T, J, 3)`` local translations of frames ``1 .. T`` (for the losses' FK)."""
        return self.positions[:, 1:]


@dataclass(frozen=True, eq=False)
class GaitData:
    """Per-frame arrays of the clips of one split and the windows cut from them.

    Frames of all clips are concatenated; a window is a first frame into that concatenation
    whose ``T + 1`` frames lie in one clip.

    Attributes:
        rotations: ``(F, J, 4)`` local unit quaternions, sign-continuous within each clip.
        positions: ``(F, J, 3)`` local translations, metres (root: world position).
        affective: ``(F, 18)`` pose affective features.
        movement: ``(F, 5)`` movement inputs.
        root: ``(F, 3)`` root features.
        heading: ``(F,)`` yaw of the body's facing (radians, 0 facing +Z;
            :func:`emotive.core.ops.heading`).
        root_xz: ``(F, 2)`` world ground position of the root role.
        clip_offsets: ``(K + 1,)`` first frame of each clip, then ``F``.
        emotions: ``(K, C)`` emotion vector of each clip.
        clips: the ``K`` clips' labels.
        starts: ``(N,)`` first frame of each window, into the ``F`` frames.
        window_clip: ``(N,)`` clip of each window.
        length: ``T``, input frames per window (windows hold ``T + 1`` frames).
        mover: joint whose local transform carries the window's world placement.
        skeleton: the rig of the first clip (names and parents shared by every clip).
        fps: frame rate.
        labels: the ``C`` labels of ``emotions``.
    """

    rotations: np.ndarray
    positions: np.ndarray
    affective: np.ndarray
    movement: np.ndarray
    root: np.ndarray
    heading: np.ndarray
    root_xz: np.ndarray
    clip_offsets: np.ndarray
    emotions: np.ndarray
    clips: tuple[ClipInfo, ...]
    starts: np.ndarray
    window_clip: np.ndarray
    length: int
    mover: int
    skeleton: Skeleton
    fps: float
    labels: tuple[str, ...]

    def __len__(self) -> int:
        return len(self.starts)

    @property
    def num_frames(self) -> int:
        """``F``."""
        return len(self.rotations)

    def statistics(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Mean and std of the network's input features over every frame.

        ``{"affective", "movement", "root"}: (mean, std)`` over every frame, float32, the
        std floored at :data:`MIN_STD`; the argument of
        :meth:`~emotive.models.gait.network.GaitNetwork.set_feature_statistics`.
        """
        if not self.num_frames:
            raise DataError("no frames to compute feature statistics from")
        out = {}
        for name in ("affective", "movement", "root"):
            x = getattr(self, name).astype(np.float64)
            out[name] = (x.mean(0).astype(np.float32),
                         np.maximum(x.std(0), MIN_STD).astype(np.float32))
        return out

    def batch(self, index: np.ndarray | Sequence[int], dtype: torch.dtype = torch.float32
              ) -> GaitBatch:
        """The windows ``index``, every frame heading-canonical (facing +Z over the origin).

        Args:
            index: ``(B,)`` window indices.
            dtype: float type of the tensors.

        Returns:
            The :class:`GaitBatch`.
        """
        first = self.starts[np.asarray(index, dtype=np.int64)]
        frames = first[:, None] + np.arange(self.length + 1)

        def cut(x: np.ndarray) -> torch.Tensor:
            return torch.from_numpy(x[frames]).to(dtype)

        return GaitBatch(
            cut(self.rotations), cut(self.positions), cut(self.affective), cut(self.movement),
            cut(self.root),
            torch.from_numpy(self.emotions[self.window_clip[np.asarray(index, dtype=np.int64)]])
            .to(dtype),
        )


def clip_features(motion: Motion) -> dict[str, np.ndarray]:
    """Per-frame quantities of one clip.

    Per-frame quantities of one clip (see the module docstring), after
    :func:`~emotive.core.root.fold_into_root`.

    Args:
        motion: the clip, ``T`` frames.

    Returns:
        ``{"rotations": (T, J, 4), "positions": (T, J, 3), "affective": (T, 18),
        "movement": (T, 5), "root": (T, 3), "heading": (T,), "root_xz": (T, 2)}``, float64.

    Raises:
        RigError: the rig lacks the roles of the features.
    """
    roles = resolve_roles(motion.skeleton)
    motion = fold_into_root(motion, int(roles.index["root"]))
    world = motion.positions_with_end_sites()
    mf = movement_features(world, roles, motion.fps)
    theta = mf.step_phase
    return {
        "rotations": quaternion_continuity(motion.rotations, dim=0),
        "positions": motion.positions,
        "affective": gait_affective_np(world, roles),
        "movement": np.stack((np.sin(theta), np.cos(theta), mf.step_frequency,
                              mf.root_speed_lowpass, mf.curvature), 1),
        "root": np.stack((mf.root_height, mf.root_speed, mf.orientation_difference), 1),
        "heading": heading(motion),
        "root_xz": world[:, roles.index["root"]][:, [0, 2]],
    }


def canonical_frames(
    rotations: np.ndarray, positions: np.ndarray, heading: np.ndarray, root_xz: np.ndarray,
    mover: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Every frame heading-canonical: facing +Z with the root role over the origin.

    ``x -> yaw(-heading_t) (x - root_t)`` on the ground plane, applied to the mover's local
    transform; the mover's quaternions are then put in the hemisphere of the first frame's (a
    yaw that wraps by ``2 pi`` flips a quaternion's sign, the rotation is the same).

    Args:
        rotations: ``(F, J, 4)`` local unit quaternions.
        positions: ``(F, J, 3)`` local translations.
        heading: ``(F,)`` body facing yaw, radians.
        root_xz: ``(F, 2)`` ground position of the root role.
        mover: the joint carrying the world placement.

    Returns:
        ``(F, J, 4)`` rotations and ``(F, J, 3)`` translations (new arrays).
    """
    yaw = yaw_quaternion(-np.asarray(heading, dtype=np.float64))
    rot, pos = rotations.copy(), positions.copy()
    shifted = positions[:, mover].copy()
    shifted[:, [0, 2]] -= root_xz
    pos[:, mover] = quaternion_apply(yaw, shifted)
    q = quaternion_multiply(yaw, rotations[:, mover])
    if len(q):
        q *= np.where((q * q[:1]).sum(-1, keepdims=True) < 0, -1.0, 1.0)
    rot[:, mover] = q
    return rot, pos


def build_gait_data(
    clips: Sequence[Clip],
    labels: Sequence[str],
    length: int,
    stride: int,
    fps: float | None = None,
    progress: bool = False,
) -> GaitData:
    """Per-frame inputs of clips and their windows of ``length + 1`` frames.

    Args:
        clips: clips of one rig (one split); each clip's style must be among ``labels``.
        labels: the ``C`` labels of the emotion vector.
        length: ``T``, input frames per window.
        stride: frames between window starts within a clip.
        fps: frame rate to resample the clips to; ``None`` keeps theirs (they must share it).
        progress: a progress bar on stderr.

    Returns:
        The data; clips shorter than ``length + 1`` frames give no window and are left out.

    Raises:
        DataError: no clips, bad length or stride, mixed rates without ``fps``, or clips of
            different joint hierarchies.
        EmotionError: a clip's style is not among ``labels``.
    """
    if length < 1 or stride < 1:
        raise DataError(f"window length and stride must be >= 1, got {length} and {stride}")
    if not clips:
        raise DataError("no clips to build gait training data from")
    rates = {c.motion.fps for c in clips}
    if fps is None and len(rates) > 1:
        raise DataError(f"clips have different frame rates {sorted(rates)}: pass fps=")
    target = float(fps) if fps is not None else rates.pop()
    kept = [c for c in clips if round(c.motion.num_frames * target / c.motion.fps) > length]
    if not kept:
        raise DataError(f"no clip has the {length + 1} frames a window needs")
    skeleton = kept[0].motion.skeleton
    for clip in kept:
        sk = clip.motion.skeleton
        if sk.names != skeleton.names or not np.array_equal(sk.parents, skeleton.parents):
            raise DataError(f"clip {clip.name} has another joint hierarchy than {kept[0].name}")
    mover = int(resolve_roles(skeleton).index["root"])
    parts: dict[str, list[np.ndarray]] = {}
    offsets, starts, window_clip, emotions, infos = [0], [], [], [], []
    for clip in track(kept, description="gait features", disable=not progress,
                      console=Console(stderr=True), transient=True):
        motion = clip.motion
        if abs(motion.fps - target) > 1e-9 * target:
            motion = resample(motion, target)
        feats = clip_features(motion)
        n = motion.num_frames
        if n <= length:
            continue
        for key, value in feats.items():
            parts.setdefault(key, []).append(value)
        first = window_starts(n, length + 1, stride)
        starts.append(offsets[-1] + first)
        window_clip.append(np.full(len(first), len(infos), dtype=np.int64))
        emotions.append(Emotion.one_hot(style_to_label(clip.style), labels).weights)
        infos.append(clip.info)
        offsets.append(offsets[-1] + n)

    def cat(key: str, dtype: type = np.float32) -> np.ndarray:
        return np.concatenate(parts[key]).astype(dtype)

    heading_all, root_xz = cat("heading", np.float64), cat("root_xz", np.float64)
    rotations, positions = canonical_frames(cat("rotations", np.float64),
                                            cat("positions", np.float64), heading_all, root_xz,
                                            mover)
    return GaitData(
        rotations=rotations.astype(np.float32), positions=positions.astype(np.float32),
        affective=cat("affective"), movement=cat("movement"), root=cat("root"),
        heading=heading_all, root_xz=root_xz, clip_offsets=np.array(offsets, dtype=np.int64),
        emotions=np.stack(emotions).astype(np.float32), clips=tuple(infos),
        starts=np.concatenate(starts), window_clip=np.concatenate(window_clip),
        length=int(length), mover=mover, skeleton=skeleton, fps=target, labels=tuple(labels),
    )


def load_gait_data(
    config: GaitConfig,
    datasets: Sequence[str] = DEFAULT_DATASETS,
    length: int = 60,
    stride: int = 15,
    split_seed: int = 0,
    max_clips: int = 0,
    progress: bool = False,
) -> dict[str, GaitData]:
    """The locomotion clips of ``datasets`` as gait training data, by split.

    Per data set: the locomotion clips whose style is one of ``config.labels``, split by clip
    with :func:`~emotive.data.splits.split_clips` (seed ``split_seed``); the splits of all data
    sets are then pooled. Every window is at ``config.fps``.

    Args:
        config: labels and frame rate.
        datasets: registry names.
        length: ``T``, input frames per window.
        stride: frames between window starts.
        split_seed: seed of the split by clip.
        max_clips: for quick runs, at most this many clips per split and data set, evenly
            spread over the split's clips in name order (0: all).
        progress: progress bars on stderr.

    Returns:
        ``{"train", "val", "test"}`` -> :class:`GaitData`; a split without a usable clip is
        missing.

    Raises:
        DataError: a data set is missing, or the training split has no window.
    """
    pooled: dict[str, list[Clip]] = {s: [] for s in SPLITS}
    for name in datasets:
        clips = [c for c in load_clips(name, locomotion=True, progress=progress)
                 if style_to_label(c.style) in config.labels]
        for split, members in split_clips(clips, seed=split_seed).items():
            pooled[split].extend(spread(members, max_clips))
    if not pooled["train"]:
        raise DataError(
            f"no locomotion clips of {list(datasets)} have a style among {list(config.labels)}"
        )
    out = {}
    for split, clips in pooled.items():
        usable = [c for c in clips if round(c.motion.num_frames * config.fps / c.motion.fps)
                  > length]
        if usable:
            out[split] = build_gait_data(usable, config.labels, length, stride, config.fps,
                                         progress)
    if "train" not in out:
        raise DataError(f"no training clip has the {length + 1} frames a window needs")
    return out

