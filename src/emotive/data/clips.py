"""Clips of a data set: labels from file names and JSON, loading with a preprocessing cache.

Every clip ``data/dataset-N_{content}_{style}_{take}.bvh`` has a ``.json`` beside it holding
``{"content": i, "style": k}``, indices into ``cfg/content_label.txt`` and
``cfg/style_label.txt`` (lines such as ``dataset-1_walk``). :func:`read_clip_index` checks that
the name and the JSON agree and that every label is in the registry.

:func:`load_clips` parses the BVH files once and stores their arrays in
``$EMOTIVE_HOME/preprocessed/<name>-<key>.npz``; the key is a sha256 over the archive's sha256,
the source of the code that produces the arrays (BVH reader, rotation conversions, this
module) and the loading options, so a change to any of them makes a fresh file.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import logging
import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.progress import track

import emotive
from emotive.core.motion import Motion
from emotive.core.skeleton import Skeleton
from emotive.data.emotion import style_to_label
from emotive.data.registry import DatasetInfo, get_dataset
from emotive.data.store import dataset_dir, emotive_home
from emotive.errors import DataError
from emotive.io import bvh
from emotive.io.atomic import atomic_output

log = logging.getLogger(__name__)

#: Modules whose source determines the preprocessed arrays (part of the cache key).
CACHE_SOURCES = (
    "emotive.io.bvh", "emotive.transforms.np_rotations", "emotive.core.skeleton",
    "emotive.data.clips",
)
_NAME_RE = re.compile(
    r"^dataset-(?P<dataset>\d+)_(?P<content>[a-z0-9-]+)_(?P<style>[a-z0-9-]+)_(?P<take>\d+)$"
)


def parse_clip_name(path: str | os.PathLike) -> dict[str, str] | None:
    """Labels in a Bandai Namco file name ``dataset-N_{content}_{style}_{take}.bvh``.

    Returns:
        ``{"dataset", "content", "style", "take"}`` strings, or ``None`` when the name does
        not follow the pattern.
    """
    match = _NAME_RE.match(Path(path).stem)
    return match.groupdict() if match else None


@dataclass(frozen=True)
class ClipInfo:
    """One labelled clip.

    Attributes:
        dataset: registry name of its data set.
        name: file stem, e.g. ``dataset-1_walk_happy_001``.
        path: the ``.bvh`` file.
        content: the action (``walk``, ``bow``, ...).
        style: the data set's style name (``happy``, ``normal``, ``elderly``, ...).
        take: take number from the file name.
    """

    dataset: str
    name: str
    path: Path
    content: str
    style: str
    take: int

    @property
    def emotion(self) -> str:
        """The emotion label of the style (``normal`` -> ``neutral``)."""
        return style_to_label(self.style)


@dataclass(frozen=True, eq=False)
class Clip:
    """A clip's labels and its motion (``motion.metadata`` repeats the labels)."""

    info: ClipInfo
    motion: Motion

    @property
    def name(self) -> str:
        """The clip's file stem (so loaded clips can be split like :class:`ClipInfo`)."""
        return self.info.name

    @property
    def content(self) -> str:
        """The action label."""
        return self.info.content

    @property
    def style(self) -> str:
        """The data set's style name."""
        return self.info.style


def _read_labels(path: Path, prefix: str) -> list[str]:
    try:
        lines = [ln.strip() for ln in path.read_text().splitlines() if ln.strip()]
    except OSError:
        raise DataError(f"{path} is missing: the data set is incomplete; fetch it again") from None
    bad = [ln for ln in lines if not ln.startswith(prefix)]
    if bad:
        raise DataError(f"{path}: label {bad[0]!r} does not start with {prefix!r}")
    return [ln[len(prefix):] for ln in lines]


def read_clip_index(folder: Path, dataset: str | DatasetInfo) -> list[ClipInfo]:
    """Every clip of an unpacked data set folder, checked against its labels.

    Args:
        folder: the data set folder (holding ``cfg/`` and ``data/``).
        dataset: registry name or entry; its label lists must match ``cfg/``.

    Returns:
        The clips sorted by name.

    Raises:
        DataError: a file name that does not follow ``dataset-N_{content}_{style}_{take}``, a
            missing or unreadable JSON, a JSON that disagrees with the file name, or labels that
            differ from the registry; the message names the file.
    """
    info = get_dataset(dataset)
    folder = Path(folder)
    files = sorted((folder / "data").glob("*.bvh"))
    if not files:
        raise DataError(f"{folder / 'data'} holds no .bvh files; fetch {info.name} again")
    number = _NAME_RE.match(files[0].stem)
    prefix = f"dataset-{number.group(1)}_" if number else "dataset-"
    contents = _read_labels(folder / "cfg" / "content_label.txt", prefix)
    styles = _read_labels(folder / "cfg" / "style_label.txt", prefix)
    if tuple(contents) != info.contents or tuple(styles) != info.styles:
        raise DataError(
            f"labels in {folder / 'cfg'} differ from the registry entry {info.name}: "
            "the folder holds another data set or a changed version"
        )
    clips = []
    for path in files:
        match = _NAME_RE.match(path.stem)
        if match is None or f"dataset-{match.group(1)}_" != prefix:
            raise DataError(
                f"{path.name}: expected a name {prefix}{{content}}_{{style}}_{{take}}.bvh"
            )
        _, content, style, take = match.groups()
        if content not in contents or style not in styles:
            raise DataError(
                f"{path.name}: content {content!r} or style {style!r} is not in {folder / 'cfg'}"
            )
        label_file = path.with_suffix(".json")
        try:
            label = json.loads(label_file.read_text())
            ids = int(label["content"]), int(label["style"])
        except FileNotFoundError:
            raise DataError(f"{label_file} is missing: every clip needs its JSON label") from None
        except (ValueError, KeyError, TypeError):
            raise DataError(
                f'{label_file} must hold {{"content": i, "style": k}} with whole numbers'
            ) from None
        if not (0 <= ids[0] < len(contents) and 0 <= ids[1] < len(styles)):
            raise DataError(f"{label_file}: label ids {ids} are out of range of {folder / 'cfg'}")
        if (contents[ids[0]], styles[ids[1]]) != (content, style):
            raise DataError(
                f"{label_file} says content {contents[ids[0]]!r} and style {styles[ids[1]]!r} but "
                f"the file name says {content!r} and {style!r}: the labels disagree"
            )
        clips.append(ClipInfo(info.name, path.stem, path, content, style, int(take)))
    return clips


def select_clips(
    clips: Iterable[ClipInfo],
    *,
    locomotion: bool = False,
    contents: Sequence[str] | None = None,
    styles: Sequence[str] | None = None,
) -> list[ClipInfo]:
    """The clips that pass the filters.

    Args:
        clips: clips of one or more data sets.
        locomotion: keep only the data set's locomotion contents (data set 1: walk, walk-back,
            walk-left, walk-right, run, dash).
        contents: keep only these contents.
        styles: keep only these styles (data set names: ``normal``, not ``neutral``).

    Raises:
        DataError: a requested content or style exists in none of the clips' data sets.
    """
    clips = list(clips)
    infos = {get_dataset(c.dataset) for c in clips}
    for wanted, field in ((contents, "contents"), (styles, "styles")):
        known = {x for i in infos for x in getattr(i, field)}
        unknown = sorted(set(wanted or ()) - known)
        if unknown:
            raise DataError(f"unknown {field} {unknown}; known: {', '.join(sorted(known))}")
    out = []
    for clip in clips:
        if locomotion and clip.content not in get_dataset(clip.dataset).locomotion:
            continue
        if contents is not None and clip.content not in contents:
            continue
        if styles is not None and clip.style not in styles:
            continue
        out.append(clip)
    return out


def list_clips(
    name: str | DatasetInfo,
    *,
    locomotion: bool = False,
    contents: Sequence[str] | None = None,
    styles: Sequence[str] | None = None,
) -> list[ClipInfo]:
    """The labelled clips of a data set (unpacked on first use), filtered.

    Args:
        name: registry name, e.g. ``"bandai-namco-1"``.
        locomotion: filter, see :func:`select_clips`.
        contents: filter, see :func:`select_clips`.
        styles: filter, see :func:`select_clips`.
    """
    info = get_dataset(name)
    clips = read_clip_index(dataset_dir(info), info)
    return select_clips(clips, locomotion=locomotion, contents=contents, styles=styles)


def code_fingerprint() -> str:
    """sha256 over the source of :data:`CACHE_SOURCES` (the package version if unreadable)."""
    digest = hashlib.sha256(emotive.__version__.encode())
    for module_name in CACHE_SOURCES:
        module = importlib.import_module(module_name)
        try:
            digest.update(Path(module.__file__ or "").read_bytes())
        except OSError:
            digest.update(module_name.encode())
    return digest.hexdigest()


def cache_key(name: str | DatasetInfo, unit: str = "auto") -> str:
    """Content hash naming the preprocessed arrays of a data set."""
    info = get_dataset(name)
    payload = {
        "dataset": info.name, "archive_sha256": info.sha256, "code": code_fingerprint(),
        "options": {"unit": unit},
    }
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()


def preprocessed_path(name: str | DatasetInfo, unit: str = "auto") -> Path:
    """``$EMOTIVE_HOME/preprocessed/<name>-<key>.npz``."""
    info = get_dataset(name)
    return emotive_home() / "preprocessed" / f"{info.name}-{cache_key(info, unit)[:20]}.npz"


def _preprocess(
    info: DatasetInfo, clips: list[ClipInfo], unit: str, dest: Path, progress: bool
) -> None:
    """Parse every clip and store the arrays in ``dest`` atomically.

    Parse every clip (with a progress bar on stderr if asked) and store the arrays in
    ``dest`` atomically.
    """
    motions = [
        bvh.read_bvh(c.path, unit=unit)  # module attribute: tests patch it
        for c in track(clips, description=f"parsing {info.name} (once)", disable=not progress,
                       console=Console(stderr=True), transient=True)
    ]
    first = motions[0].skeleton
    for clip, m in zip(clips, motions, strict=True):
        sk = m.skeleton
        if (sk.names, sk.channels) != (first.names, first.channels) or not (
            np.array_equal(sk.parents, first.parents)
            and np.array_equal(sk.end_site_parents, first.end_site_parents)
        ):
            raise DataError(
                f"{clip.path.name} has another joint hierarchy than {clips[0].path.name}: "
                "the preprocessing cache needs one hierarchy per data set"
            )
    lengths = np.array([m.num_frames for m in motions])
    arrays = {
        "clip_names": np.array([c.name for c in clips]),
        "frame_offsets": np.concatenate(([0], np.cumsum(lengths))),
        "rotations": np.concatenate([m.rotations for m in motions]),
        "positions": np.concatenate([m.positions for m in motions]),
        "offsets": np.stack([m.skeleton.offsets for m in motions]),
        "end_site_offsets": np.stack([m.skeleton.end_site_offsets for m in motions]),
        "fps": np.array([m.fps for m in motions]),
        "file_units": np.array([m.metadata.get("file_unit", "") for m in motions]),
        "parents": first.parents,
        "end_site_parents": first.end_site_parents,
        "rig": np.array(json.dumps({"names": first.names, "channels": first.channels})),
        "key": np.array(cache_key(info, unit)),
    }
    dest.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(dest) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **arrays)
    for stale in dest.parent.glob(f"{info.name}-*.npz"):
        if stale != dest:
            stale.unlink(missing_ok=True)


def _preprocessed(
    info: DatasetInfo, unit: str, progress: bool = False
) -> tuple[Path, list[ClipInfo]]:
    """The preprocessed file of a data set (made on first use) and its clips, in file order."""
    clips = read_clip_index(dataset_dir(info), info)
    dest = preprocessed_path(info, unit)
    if dest.is_file():
        with np.load(dest, allow_pickle=False) as data:
            names = data["clip_names"].tolist()
        if names == [c.name for c in clips]:
            return dest, clips
        log.info("%s does not match the clips of %s; rebuilding it", dest, info.name)
    log.info("parsing %d clips of %s (once; cached in %s)", len(clips), info.name, dest)
    _preprocess(info, clips, unit, dest, progress)
    return dest, clips


def frame_counts(
    name: str | DatasetInfo, unit: str = "auto", progress: bool = False
) -> dict[str, int]:
    """``{clip name: frames}`` of every clip, from the preprocessing cache.

    ``{clip name: frames}`` of every clip, from the preprocessing cache (made on first use,
    with a progress bar if ``progress``).
    """
    info = get_dataset(name)
    path, clips = _preprocessed(info, unit, progress)
    with np.load(path, allow_pickle=False) as data:
        lengths = np.diff(data["frame_offsets"])
    return {c.name: int(n) for c, n in zip(clips, lengths, strict=True)}


def load_clips(
    name: str | DatasetInfo,
    *,
    locomotion: bool = False,
    contents: Sequence[str] | None = None,
    styles: Sequence[str] | None = None,
    unit: str = "auto",
    progress: bool = False,
) -> list[Clip]:
    """Load the motions of a data set's clips, through the preprocessing cache.

    The first call parses every BVH file of the data set (a few seconds) and stores the arrays;
    later calls read them back from one ``.npz`` file.

    Args:
        name: registry name, e.g. ``"bandai-namco-1"``.
        locomotion: filter, see :func:`select_clips`.
        contents: filter, see :func:`select_clips`.
        styles: filter, see :func:`select_clips`.
        unit: file length unit passed to :func:`emotive.io.bvh.read_bvh`.
        progress: show a progress bar on stderr while the first call parses the files.

    Returns:
        The clips sorted by name; each motion's ``metadata`` holds ``name``, ``source``,
        ``file_unit``, ``dataset``, ``content``, ``style``, ``take`` and ``emotion``.
    """
    info = get_dataset(name)
    path, all_clips = _preprocessed(info, unit, progress)
    wanted = select_clips(all_clips, locomotion=locomotion, contents=contents, styles=styles)
    index = {c.name: i for i, c in enumerate(all_clips)}
    with np.load(path, allow_pickle=False) as data:
        arrays = {key: data[key] for key in data.files}
    rig = json.loads(str(arrays["rig"]))
    names = tuple(rig["names"])
    channels = tuple(tuple(c) for c in rig["channels"])
    skeletons: dict[bytes, Skeleton] = {}
    out = []
    for clip in wanted:
        i = index[clip.name]
        offsets, ends = arrays["offsets"][i], arrays["end_site_offsets"][i]
        rig_key = offsets.tobytes() + ends.tobytes()
        if rig_key not in skeletons:
            skeletons[rig_key] = Skeleton(
                names, arrays["parents"], offsets, channels, arrays["end_site_parents"], ends
            )
        lo, hi = arrays["frame_offsets"][i], arrays["frame_offsets"][i + 1]
        metadata = {
            "name": clip.name, "source": str(clip.path), "file_unit": str(arrays["file_units"][i]),
            "dataset": clip.dataset, "content": clip.content, "style": clip.style,
            "take": clip.take, "emotion": clip.emotion,
        }
        motion = Motion(
            skeletons[rig_key], arrays["rotations"][lo:hi], arrays["positions"][lo:hi],
            float(arrays["fps"][i]), metadata,
        )
        out.append(Clip(clip, motion))
    return out
