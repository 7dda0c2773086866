"""``emotive export web``: a static folder that runs gait agents in the browser.

The folder holds everything the page needs and nothing it must fetch elsewhere:

==============================  ==========================================================
``index.html``, ``*.js``        the page (:data:`PAGE`): the engine loop of ``docs/runtime.md``
                                on onnxruntime-web, the scene, the controls, the test hook
``scene-setup.js``, ...         the served app's view, figures, mouse input, cameras, panel,
                                emotion controls and WebXR buttons (:data:`SHARED`, copied
                                from ``emotive/serve/static``)
``vendor/three/``               three.js, as the served app vendors it
``vendor/onnxruntime-web/``     onnxruntime-web's WebAssembly build, its licence and notices
                                (:data:`RUNTIME_SOURCE`, from ``emotive/assets``)
``vendor/recast-navigation/``   recast-navigation's ES modules and WebAssembly build (Recast
                                and Detour), its licences (:data:`RECAST_SOURCE`); the page
                                loads its WebAssembly only for a scene
``agent.onnx``                  the whole agent step (:func:`export_agent_step`)
``agent.json``                  the step's metadata, the rig and the emotion points
``mannequin.glb``               the skinned mannequin of the served app's ``/api/mannequin.glb``
``scene.json``                  with a crowd scene only: what the page needs to run it
                                (:func:`~emotive.web.scene.scene_document`); ``agent.json``
                                then names it under ``scene``
==============================  ==========================================================

The folder appears whole or not at all: it is written beside ``out`` under a temporary name
and renamed into place.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from emotive.core import Motion
from emotive.crowd.emotion_table import navigation_table
from emotive.crowd.scene import Scene
from emotive.data.circumplex import VA_KERNEL_WIDTH, label_points
from emotive.errors import ConfigError, OutputError
from emotive.io.atomic import output_error
from emotive.io.gltf import encode_gltf, gltf_document
from emotive.models.gait.agent_inputs import point_labels
from emotive.models.gait.model import GaitModel
from emotive.models.gait.step_export import STEP_INPUTS, STEP_OUTPUTS, export_agent_step
from emotive.models.gait.step_runtime import read_step_metadata
from emotive.web.scene import SCENE_FILE, scene_document

#: ``format`` of ``agent.json``.
WEB_FORMAT = "emotive-web/1"
#: The page's own files.
PAGE = Path(__file__).with_name("static")
#: The served app's folder, whose renderer the page reuses.
SERVE_STATIC = Path(__file__).parents[1] / "serve" / "static"
#: Files and folders of :data:`SERVE_STATIC` copied unchanged into the export.
SHARED: tuple[str, ...] = ("app.css", "scene-setup.js", "ground-input.js", "agent-figures.js",
                           "follow-camera.js", "panel.js", "figures.js", "emotion-controls.js",
                           "xr.js", "vendor/three")
#: Where the export puts the vendored runtime, relative to the page.
RUNTIME = "vendor/onnxruntime-web"
#: The vendored runtime in the package (with the package's other large files).
RUNTIME_SOURCE = Path(__file__).parents[1] / "assets" / "onnxruntime-web"
#: Where the export puts recast-navigation, and where the package keeps it.
RECAST = "vendor/recast-navigation"
RECAST_SOURCE = Path(__file__).parents[1] / "assets" / "recast-navigation"
#: Names of the generated files.
GRAPH, METADATA, MANNEQUIN = "agent.onnx", "agent.json", "mannequin.glb"
#: Metadata entries of the graph that hold JSON.
_JSON_KEYS = ("labels", "path_sampling", "inputs", "outputs", "joint_names", "parents",
              "end_site_parents")


@dataclass(frozen=True)
class WebExport:
    """What :func:`export_web` wrote.

    Attributes:
        folder: the folder.
        files: number of files in it.
        total_bytes: their size.
        graph_bytes: the size of ``agent.onnx``.
        runtime_bytes: the size of the vendored onnxruntime-web.
        scene_agents: agents the scene spawns (a flow without a count: 0), or ``None``
            without a scene.
    """

    folder: Path
    files: int
    total_bytes: int
    graph_bytes: int
    runtime_bytes: int
    scene_agents: int | None = None


def _size(folder: Path) -> tuple[int, int]:
    files = [p for p in folder.rglob("*") if p.is_file()]
    return len(files), sum(p.stat().st_size for p in files)


def web_metadata(model: GaitModel, step: dict[str, str]) -> dict[str, Any]:
    """The content of ``agent.json``.

    Args:
        model: the exported model.
        step: the graph's ``metadata_props`` (:func:`read_step_metadata`).

    Returns:
        ``format``; ``graph`` and ``mannequin`` (file names); ``step``: the graph's metadata
        an engine needs (``fps``, ``labels``, ``path_sampling``, ``warmup_steps``,
        ``loop_left``, ``inputs``/``outputs`` shapes and names, provenance); ``skeleton``: the
        rig as ``/api/skeleton`` gives it (``joints``, ``parents``, ``end_site_parents``,
        ``offsets``, ``mover``); ``emotion``: ``labels``, each label's valence/arousal
        ``points``, the ``point_labels`` a valence/arousal point blends and the blend's
        ``kernel_width``; ``navigation``: the crowd's emotion-to-navigation table with each
        label's parameters for Unity, Unreal and Godot
        (:func:`~emotive.crowd.emotion_table.navigation_table`).
    """
    sk = model.controls.skeleton
    labels = list(model.labels)
    info = {k: json.loads(step[k]) if k in _JSON_KEYS else step[k]
            for k in ("format", "labels", "path_sampling", "inputs", "outputs", "opset",
                      "emotive_version", "weights_sha256")}
    info.update(fps=float(step["fps"]), warmup_steps=int(step["warmup_steps"]),
                loop_left=float(step["loop_left"]), input_names=list(STEP_INPUTS),
                output_names=list(STEP_OUTPUTS))
    points = label_points(labels)
    return {
        "format": WEB_FORMAT,
        "graph": GRAPH,
        "mannequin": MANNEQUIN,
        "model": model.source.name,
        "step": info,
        "skeleton": {
            "joints": list(sk.names), "parents": [int(p) for p in sk.parents],
            "end_site_parents": [int(p) for p in sk.end_site_parents],
            "offsets": np.round(sk.offsets, 6).tolist(), "mover": int(model.controls.mover),
        },
        "emotion": {
            "labels": labels,
            "points": {n: [round(float(v), 4), round(float(a), 4)]
                       for n, (v, a) in zip(labels, points, strict=True)},
            "point_labels": list(point_labels(labels) or labels),
            "kernel_width": VA_KERNEL_WIDTH,
        },
        "navigation": navigation_table(labels, np.asarray(model.controls.speed) * model.fps),
    }


def mannequin_glb(model: GaitModel) -> bytes:
    """The skinned mannequin in the standing pose, as ``/api/mannequin.glb`` of ``serve``."""
    c = model.controls
    rest = Motion(c.skeleton, np.asarray(c.standing_rotations)[None],
                  np.asarray(c.standing_positions)[None], model.fps, {"name": "mannequin"})
    doc, blob = gltf_document(rest, mesh=True)
    return encode_gltf(doc, blob, binary=True)


def _is_export(folder: Path) -> bool:
    """Whether ``folder`` holds a previous web export (its ``agent.json`` says so)."""
    try:
        meta = json.loads((folder / METADATA).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(meta, dict) and meta.get("format") == WEB_FORMAT


def check_web_folder(out: Path, force: bool) -> None:
    """Fail early on an output folder that cannot take the export.

    Raises:
        OutputError: ``out`` is a file, a non-empty folder without ``force``, a folder with
            other files than a previous export (``force`` replaces only an export), or its
            parent is missing; naming the fix.
    """
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out}: that is a file; name a folder for the page")
    if out.is_dir() and any(out.iterdir()):
        if not force:
            raise OutputError(f"--out {out}: the folder exists and is not empty; choose a new "
                              "folder, or add --force to replace a previous export")
        if not _is_export(out):
            raise OutputError(f"--out {out}: the folder holds files that are not an emotive "
                              "web export, which --force does not replace; choose a new or "
                              "empty folder")
    if not out.parent.is_dir():
        raise OutputError(f"--out {out}: folder {out.parent} does not exist; create it first")


def _copy(src: Path, dest: Path) -> None:
    if not src.exists():
        raise ConfigError(f"{src} is missing from this installation of emotive (the page "
                          "needs it); reinstall emotive")
    if not src.is_dir():
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, dest)
        return
    # File by file rather than shutil.copytree, which gathers its failures into one
    # shutil.Error whose text lists every file and has no errno: the first OSError (a full
    # disk, say) is raised as it is, for output_error's one line.
    for item in sorted(src.rglob("*")):
        if "__pycache__" in item.parts or item.suffix == ".pyc":
            continue
        target = dest / item.relative_to(src)
        if item.is_dir():
            target.mkdir(parents=True, exist_ok=True)
        else:
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(item, target)


def _write(model: GaitModel, work: Path, scene: dict[str, Any] | None) -> None:
    """Every file of the export into ``work``; ``scene``: the content of ``scene.json``."""
    _copy(PAGE, work)
    _copy(RUNTIME_SOURCE, work / RUNTIME)
    _copy(RECAST_SOURCE, work / RECAST)
    for name in SHARED:
        _copy(SERVE_STATIC / name, work / name)
    export_agent_step(model, work / GRAPH)
    meta = web_metadata(model, read_step_metadata(work / GRAPH))
    if scene is not None:
        meta["scene"] = SCENE_FILE
        (work / SCENE_FILE).write_text(json.dumps(scene) + "\n", encoding="utf-8")
    (work / METADATA).write_text(json.dumps(meta, indent=1) + "\n", encoding="utf-8")
    (work / MANNEQUIN).write_bytes(mannequin_glb(model))
    for path in work.rglob("*"):
        path.chmod(0o755 if path.is_dir() else 0o644)
    work.chmod(0o755)


def _replace(work: Path, out: Path) -> None:
    """Rename ``work`` to ``out``, replacing what ``out`` held only once ``work`` is there."""
    old = None
    if out.is_dir() and not any(out.iterdir()):
        out.rmdir()
    elif out.exists():
        old = out.with_name(f".{out.name}.{secrets.token_hex(4)}.old")
        out.rename(old)
    try:
        work.rename(out)
    except BaseException:
        if old is not None:
            old.rename(out)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def export_web(model: GaitModel, out: str | os.PathLike, force: bool = False,
               scene: Scene | None = None) -> WebExport:
    """Write the static folder of the browser runtime for ``model``'s agents.

    Args:
        model: the gait model whose whole step the page runs.
        out: the folder to write (made; its parent must exist).
        force: replace ``out`` when it holds a previous export.
        scene: a crowd scene (:func:`~emotive.crowd.scene.load_scene`) the page runs with
            recast-navigation's Detour crowd; ``None``: the page starts empty, as without.

    Returns:
        What was written.

    Raises:
        OutputError: see :func:`check_web_folder`, or the disk refused a write (nothing is
            left behind).
        ConfigError: a file of the page is missing from this installation, or a scene
            without shapely (the crowd extra).
        SceneError: the scene's geometry, or an emotion the model does not know.
        OnnxUnavailableError: ``onnx`` is not installed.
    """
    out = Path(out).expanduser().absolute()
    check_web_folder(out, force)
    document = None if scene is None else scene_document(scene, model.labels)
    try:
        work = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    except OSError as exc:
        raise output_error(out, exc) from exc
    try:
        _write(model, work, document)
        files, total = _size(work)
        graph = (work / GRAPH).stat().st_size
        runtime = _size(work / RUNTIME)[1]
        _replace(work, out)
    except OSError as exc:
        raise output_error(out, exc) from exc
    finally:
        with contextlib.suppress(OSError):
            if work.exists():
                shutil.rmtree(work)
    agents = None if scene is None else sum(g.count for g in scene.groups)
    return WebExport(out, files, total, graph, runtime, agents)
