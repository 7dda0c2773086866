"""Fixed-length training windows cut from clips, with resampling and mirror augmentation.

Windows never cross clips, so a window belongs to its clip's split (:mod:`emotive.data.splits`).
A clip is first resampled to the requested frame rate with :func:`emotive.core.ops.resample`
(skipped when it already has that rate), then cut into windows of ``length`` frames every
``stride`` frames; a clip shorter than ``length`` gives none. With ``mirror=True`` each clip's
left/right mirror image from :func:`emotive.core.ops.mirror` is cut as well; it keeps the
clip's style, and its content swaps ``left`` and ``right`` (``walk-left`` -> ``walk-right``).

Shapes: ``N`` windows, ``L`` frames per window, ``J`` joints, ``C`` emotion labels.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from emotive.core.motion import Motion
from emotive.core.skeleton import Skeleton
from emotive.data.clips import Clip, ClipInfo
from emotive.data.emotion import DEFAULT_LABELS, Emotion
from emotive.errors import DataError


@dataclass(frozen=True, eq=False)
class Windows:
    """A batch of windows with their provenance.

    Attributes:
        rotations: ``(N, L, J, 4)`` local unit quaternions ``w, x, y, z``.
        positions: ``(N, L, J, 3)`` local translations in metres (root: world position).
        clip_index: ``(N,)`` index into ``clips`` of each window's clip.
        start: ``(N,)`` first frame of each window, counted at ``fps``.
        mirrored: ``(N,)`` whether the window comes from the mirrored clip.
        clips: the clips the windows were cut from.
        skeleton: the joint hierarchy shared by every clip (names and parents). Bone lengths
            may differ between clips: ``positions`` holds every joint's local translation, so
            forward kinematics needs only ``skeleton.parents``.
        fps: frame rate of the windows.
    """

    rotations: np.ndarray
    positions: np.ndarray
    clip_index: np.ndarray
    start: np.ndarray
    mirrored: np.ndarray
    clips: tuple[ClipInfo, ...]
    skeleton: Skeleton
    fps: float

    def __len__(self) -> int:
        return len(self.clip_index)

    @property
    def styles(self) -> list[str]:
        """The data set style of each window."""
        return [self.clips[i].style for i in self.clip_index]

    @property
    def contents(self) -> list[str]:
        """The content of each window, with ``left``/``right`` swapped for mirrored ones."""
        return [
            mirror_content(self.clips[i].content) if m else self.clips[i].content
            for i, m in zip(self.clip_index, self.mirrored, strict=True)
        ]

    def emotions(self, labels: Sequence[str] = DEFAULT_LABELS) -> np.ndarray:
        """``(N, C)`` one-hot emotion of each window's style over ``labels``.

        Raises:
            EmotionError: a window's style is not among ``labels`` (filter the clips by style).
        """
        table = np.stack([Emotion.one_hot(c.style, labels).weights for c in self.clips])
        return table[self.clip_index] if len(self) else np.zeros((0, len(labels)))


def mirror_content(content: str) -> str:
    """Swap ``left`` and ``right`` in a content name."""
    swap = {"left": "right", "right": "left"}
    return "-".join(swap.get(part, part) for part in content.split("-"))


def window_starts(num_frames: int, length: int, stride: int) -> np.ndarray:
    """``(W,)`` first frames of the windows of a clip of ``num_frames`` frames."""
    if length < 1 or stride < 1:
        raise DataError(f"window length and stride must be >= 1, got {length} and {stride}")
    if num_frames < length:
        return np.zeros(0, dtype=np.int64)
    return np.arange(0, num_frames - length + 1, stride, dtype=np.int64)


def _ops():
    """:mod:`emotive.core.ops`, looked up when needed (its functions are not in this package)."""
    try:
        return importlib.import_module("emotive.core.ops")
    except ModuleNotFoundError as exc:
        raise DataError(
            f"emotive.core.ops is missing ({exc}): resampling and mirroring need it; "
            "use fps equal to the file rate and mirror=False"
        ) from None


def _cut(array: np.ndarray, starts: np.ndarray, length: int) -> np.ndarray:
    """``(W, L, ...)`` windows of a ``(T, ...)`` array at ``starts``."""
    if len(starts) == 0:
        return np.zeros((0, length, *array.shape[1:]), dtype=array.dtype)
    view = np.lib.stride_tricks.sliding_window_view(array, length, axis=0)
    return np.moveaxis(view[starts], -1, 1)


def make_windows(
    clips: Sequence[Clip],
    length: int,
    stride: int,
    fps: float | None = None,
    mirror: bool = False,
    dtype: type = np.float32,
) -> Windows:
    """Cut clips into windows.

    Args:
        clips: loaded clips (:func:`emotive.data.clips.load_clips`), e.g. one split.
        length: frames per window ``L``, at ``fps``.
        stride: frames between window starts, at ``fps``.
        fps: frame rate of the windows; ``None`` keeps the clips' rate (they must share it).
        mirror: add the mirror image of every clip.
        dtype: float type of the arrays.

    Returns:
        The windows, clip by clip in input order, the mirrored copy after the original.

    Raises:
        DataError: bad length or stride, mixed frame rates with ``fps=None``, or
            :mod:`emotive.core.ops` missing when resampling or mirroring is asked for.
    """
    if length < 1 or stride < 1:
        raise DataError(f"window length and stride must be >= 1, got {length} and {stride}")
    rates = {c.motion.fps for c in clips}
    if fps is None and len(rates) > 1:
        raise DataError(f"clips have different frame rates {sorted(rates)}: pass fps=")
    target = float(fps) if fps is not None else (rates.pop() if rates else 30.0)
    if not clips:
        raise DataError("no clips to cut into windows")
    skeleton = clips[0].motion.skeleton
    rot_parts, pos_parts, index_parts, start_parts, mirror_parts = [], [], [], [], []
    for i, clip in enumerate(clips):
        motion: Motion = clip.motion
        sk = motion.skeleton
        if sk.names != skeleton.names or not np.array_equal(sk.parents, skeleton.parents):
            raise DataError(
                f"clip {clip.info.name} has another joint hierarchy than {clips[0].info.name}: "
                "cut windows from clips of one rig"
            )
        if abs(motion.fps - target) > 1e-9 * target:
            motion = _ops().resample(motion, target)
        variants = [(motion, False)]
        if mirror:
            variants.append((_ops().mirror(motion), True))
        for m, flag in variants:
            starts = window_starts(m.num_frames, length, stride)
            rot_parts.append(_cut(m.rotations.astype(dtype, copy=False), starts, length))
            pos_parts.append(_cut(m.positions.astype(dtype, copy=False), starts, length))
            index_parts.append(np.full(len(starts), i, dtype=np.int64))
            start_parts.append(starts)
            mirror_parts.append(np.full(len(starts), flag))
    return Windows(
        rotations=np.concatenate(rot_parts),
        positions=np.concatenate(pos_parts),
        clip_index=np.concatenate(index_parts),
        start=np.concatenate(start_parts),
        mirrored=np.concatenate(mirror_parts).astype(bool),
        clips=tuple(c.info for c in clips),
        skeleton=skeleton,
        fps=target,
    )
