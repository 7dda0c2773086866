"""``emotive export web``: the folder it writes, what it prints, the path arithmetic of the
page against Python's, and one-line failures that leave nothing behind."""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from emotive.commands.export import app
from emotive.errors import OutputError
from emotive.models.gait.model import load_gait_model
from emotive.models.gait.step_runtime import read_step_metadata
from emotive.paths import GroundPath, waypoints
from emotive.paths.bank import PathBank
from emotive.web import export as web_export_module
from emotive.web.export import PAGE, SHARED, WEB_FORMAT
from tools import require_tool


def _invoke(*args: object):
    return CliRunner().invoke(app, ["web", *map(str, args)], env={"COLUMNS": "200"})


def test_the_folder_holds_the_page_the_runtime_the_graph_and_the_mannequin(web_export):
    folder = web_export.folder
    first = web_export.output.splitlines()[0]
    assert first.startswith(f"wrote {folder} (") and "agent.onnx" in first
    assert "python -m http.server" in web_export.output
    for name in ("index.html", "app.js", "engine.js", "paths.js", "agent.onnx", "agent.json",
                 "mannequin.glb", "vendor/onnxruntime-web/ort.wasm.bundle.min.mjs",
                 "vendor/onnxruntime-web/ort-wasm-simd-threaded.wasm",
                 "vendor/onnxruntime-web/LICENSE", "vendor/onnxruntime-web/VENDOR.md",
                 "vendor/three/three.module.js", "vendor/three/LICENSE", *SHARED):
        assert (folder / name).exists(), name
    assert (folder / "mannequin.glb").read_bytes()[:4] == b"glTF"
    # Nothing but the export beside it: the temporary folder was renamed into place.
    assert [p.name for p in folder.parent.iterdir()] == [folder.name]


def test_agent_json_states_the_graphs_metadata_the_rig_and_the_emotion_points(web_export):
    meta = json.loads((web_export.folder / "agent.json").read_text())
    graph = read_step_metadata(web_export.folder / "agent.onnx")
    model = load_gait_model()
    step = meta["step"]
    assert meta["format"] == WEB_FORMAT and meta["graph"] == "agent.onnx"
    assert step["labels"] == json.loads(graph["labels"]) == list(model.labels)
    assert step["path_sampling"] == json.loads(graph["path_sampling"])
    assert step["inputs"] == json.loads(graph["inputs"])
    assert step["fps"] == float(graph["fps"]) == model.fps
    assert step["warmup_steps"] == int(graph["warmup_steps"])
    assert step["weights_sha256"] == graph["weights_sha256"]
    assert list(step["inputs"]) == step["input_names"]
    assert meta["skeleton"]["joints"] == list(model.controls.skeleton.names)
    assert meta["skeleton"]["mover"] == model.controls.mover
    assert set(meta["emotion"]["points"]) == set(model.labels)
    assert meta["emotion"]["point_labels"] == ["happy", "sad", "angry", "neutral"]


def test_every_url_of_the_page_is_relative(web_export):
    """No CDN and no absolute path: the folder works under any static server and prefix."""
    folder = web_export.folder
    html = (folder / "index.html").read_text()
    for url in re.findall(r'(?:src|href)="([^"]+)"', html):
        assert url.startswith("./") or url.startswith("data:"), url
    imports = json.loads(re.search(r'<script type="importmap">(.*?)</script>', html,
                                   re.S).group(1))["imports"]
    assert all(v.startswith("./vendor/") for v in imports.values())
    for script in folder.glob("*.js"):
        text = script.read_text()
        static = re.findall(r'^\s*(?:import|export)\b[^;]*?from\s+"([^"]+)"', text, re.M)
        dynamic = re.findall(r"\bimport\(([^)]*)\)", text)
        for spec in static:
            assert spec.startswith(("./", "three")), (script, spec)
        # The one dynamic import: onnxruntime-web beside the page.
        assert dynamic in ([], ["ORT_MODULE"]), (script, dynamic)
        assert "https://" not in text.replace("on https:// or localhost", ""), script
    assert 'ORT_FOLDER = "./vendor/onnxruntime-web/"' in (folder / "runtime.js").read_text()


def test_a_non_empty_folder_is_refused_without_force_and_nothing_is_written(tmp_path):
    site = tmp_path / "site"
    site.mkdir()
    (site / "notes.txt").write_text("mine")
    result = _invoke("--out", site)
    assert result.exit_code != 0 and isinstance(result.exception, OutputError)
    message = str(result.exception)
    assert "\n" not in message and "--force" in message and str(site) in message
    assert [p.name for p in site.iterdir()] == ["notes.txt"]
    # --force replaces only a previous export, never a folder of other files.
    result = _invoke("--out", site, "--force")
    assert isinstance(result.exception, OutputError)
    assert "not an emotive web export" in str(result.exception)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["site"]
    result = _invoke("--out", site / "notes.txt")
    assert isinstance(result.exception, OutputError) and "is a file" in str(result.exception)


def _copy_graph(source: Path):
    """An ``export_agent_step`` that copies a finished export's graph (fast)."""
    def export(model, out_path, foot_lock=True):
        shutil.copy(source / "agent.onnx", out_path)
        return Path(out_path)
    return export


def test_force_replaces_a_previous_export(tmp_path, web_export, monkeypatch):
    site = tmp_path / "site"
    shutil.copytree(web_export.folder, site)
    (site / "stale.js").write_text("// from an older export")
    monkeypatch.setattr(web_export_module, "export_agent_step", _copy_graph(web_export.folder))
    assert _invoke("--out", site).exit_code != 0
    result = _invoke("--out", site, "--force")
    assert result.exit_code == 0, result.output
    assert not (site / "stale.js").exists() and (site / "agent.onnx").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["site"]


def test_a_failed_export_leaves_nothing_behind(tmp_path, monkeypatch):
    def fail(model, out_path, foot_lock=True):
        raise OutputError(f"cannot write {out_path}: the disk is full; free space")

    monkeypatch.setattr(web_export_module, "export_agent_step", fail)
    result = _invoke("--out", tmp_path / "site")
    assert isinstance(result.exception, OutputError)
    assert list(tmp_path.iterdir()) == []


def test_a_full_disk_while_copying_the_runtime_is_one_line(tmp_path, web_export, monkeypatch):
    copyfile = shutil.copyfile

    def full_for_wasm(src, dst, *args, **kwargs):
        if str(src).endswith(".wasm"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(dst))
        return copyfile(src, dst, *args, **kwargs)

    monkeypatch.setattr(shutil, "copyfile", full_for_wasm)
    monkeypatch.setattr(web_export_module, "export_agent_step", _copy_graph(web_export.folder))
    result = _invoke("--out", tmp_path / "site")
    message = str(result.exception)
    assert isinstance(result.exception, OutputError), result.output
    assert "the disk is full" in message and "\n" not in message and len(message) < 300
    assert list(tmp_path.iterdir()) == []


#: Run by node: paths.js on the cases of the parity test, printed as JSON.
PATHS_SCRIPT = """
import { GroundPath, waypointPath, circlePath } from "./paths.js";
const cases = JSON.parse(process.argv[2]);
const out = cases.map((c) => {
  const path = c.waypoints ? waypointPath(c.points) : new GroundPath(c.points, c.closed);
  const buffer = new Float32Array(2 * c.offsets.length);
  return c.arcs.map((arc, i) => {
    path.samples(arc, Float64Array.from(c.offsets), c.ground[i], buffer, 0);
    return Array.from(buffer);
  }).concat([[path.length, path.nearest(...c.near)]]);
});
const circle = circlePath(2.5, -2, 1.5);
out.push([[circle.length, circle.xs[0], circle.zs[0]]]);
console.log(JSON.stringify(out));
"""


def test_the_pages_path_samples_match_python(tmp_path):
    """paths.js against PathBank.ahead and to_agent_frame: loops wrap, open paths continue
    straight past their ends, drawn waypoints are the same spline."""
    from emotive.models.gait.step_path import to_agent_frame

    node = shutil.which("node")
    require_tool(node is not None, "node is not installed (apt-get install nodejs)")
    shutil.copy(PAGE / "paths.js", tmp_path / "paths.js")
    (tmp_path / "run.mjs").write_text(PATHS_SCRIPT)
    rng = np.random.default_rng(0)
    offsets = (-0.2 + 0.05 * np.arange(15)).tolist()
    drawn = np.array([[0.0, 0.0], [1.0, 0.4], [1.5, 1.5], [1.0, 2.5], [0.2, 3.1]])
    circle = np.stack((2 * (1 - np.cos(np.linspace(0, 2 * np.pi, 1200))),
                       2 * np.sin(np.linspace(0, 2 * np.pi, 1200))), -1)
    paths = [(GroundPath.from_polyline(circle, closed=True), circle, True, False),
             (waypoints(drawn), drawn, False, True),
             (GroundPath.from_polyline(drawn), drawn, False, False)]
    cases = []
    for path, points, closed, spline in paths:
        arcs = [-0.5, 0.0, 0.37, path.length - 0.1, path.length + 0.3, 3 * path.length + 0.2]
        ground = rng.uniform(-1, 1, (len(arcs), 3)).tolist()
        cases.append({"points": points.tolist(), "closed": closed, "waypoints": spline,
                      "arcs": arcs, "offsets": offsets, "ground": ground, "near": [1.2, 0.9]})
    run = subprocess.run([node, "run.mjs", json.dumps(cases)], cwd=tmp_path, check=True,
                         capture_output=True, text=True, timeout=120)
    results = json.loads(run.stdout)
    for (path, _, _, _), case, result in zip(paths, cases, results, strict=False):
        bank = PathBank()
        slot = bank.add(path)
        arcs = np.array(case["arcs"])
        world = bank.ahead(np.full(len(arcs), slot), arcs, np.array(offsets))
        ground = np.array(case["ground"])
        want = to_agent_frame(world, ground[:, :2], ground[:, 2]).astype(np.float32)
        got = np.array(result[:-1]).reshape(want.shape)
        np.testing.assert_allclose(got, want, atol=2e-6)
        length, near = result[-1]
        assert length == pytest.approx(path.length, abs=1e-9)
        assert near == pytest.approx(float(path.nearest(np.array([1.2, 0.9]))[0]), abs=1e-9)
    ((length, x0, z0),) = results[-1]
    assert length == pytest.approx(2 * np.pi * 1.5, rel=1e-4)
    assert (x0, z0) == pytest.approx((1.0, -2.0), abs=1e-3)


def test_agent_json_carries_the_emotion_to_navigation_table(web_export):
    meta = json.loads((web_export.folder / "agent.json").read_text())
    nav, model = meta["navigation"], load_gait_model()
    assert nav["columns"] == ["desired_speed", "radius", "time_gap", "yield_strength",
                              "yield_range"]
    assert list(nav["rows"]) == list(model.labels) == list(nav["engines"])
    speed = np.asarray(model.controls.speed) * model.fps
    np.testing.assert_allclose([nav["rows"][n][0] for n in model.labels], speed, atol=1e-4)
    unity = {n: nav["engines"][n]["unity"]["avoidancePriority"] for n in model.labels}
    godot = {n: nav["engines"][n]["godot"]["avoidance_priority"] for n in model.labels}
    # Angry yields least (others give way: most important), sad most; neutral is the default.
    assert unity["angry"] < unity["happy"] <= unity["neutral"] == 50 < unity["sad"] <= 99
    assert godot["angry"] > godot["neutral"] > godot["sad"] >= 0
    for n in model.labels:
        row, engines = dict(zip(nav["columns"], nav["rows"][n], strict=True)), nav["engines"][n]
        assert engines["unreal"]["AgentRadius"] == pytest.approx(100 * row["radius"], abs=0.01)
        assert engines["godot"]["time_horizon_agents"] == pytest.approx(row["time_gap"],
                                                                         abs=1e-3)
