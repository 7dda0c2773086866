"""``emotive export web --scene``: a crowd in the browser-only page, avoiding each other with
recast-navigation's Detour crowd.

The export writes ``scene.json`` (the walkable area as triangles, spawn places, goals,
emotions resolved to weights, the emotion-to-navigation table) and vendors recast-navigation;
node checks the page's crowd arithmetic against Python's; headless Chromium runs 50 agents
crossing a 12 m square with an obstacle in the middle and the test reads every body's hips
from the page's hook. Waits are on the page's state (frames stepped through the hook, the
crowd's ``done``), bounded by a frame count, never by the clock.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner
from web_helpers import HANG_SECONDS, closest_hips, open_page, run_crowd, static_server

from emotive.commands.export import app
from emotive.crowd.emotion_table import engine_parameters, navigation_params, navigation_rows
from emotive.crowd.errors import SceneError
from emotive.models.gait.agent_inputs import to_model_schedule
from emotive.models.gait.model import load_gait_model
from emotive.web.export import PAGE, RECAST
from tools import headless_chromium, require_tool

shapely = pytest.importorskip("shapely", reason="--scene needs the crowd extra (shapely)")

#: 25 agents walk west to east and 25 south to north across a 12 m square with a 2 m block in
#: the middle; happy, neutral, angry and sad drawn 3:3:2:2.
SQUARE = """
name = "square"

[area]
polygon = [[0, 0], [12, 0], [12, 12], [0, 12]]

[[area.obstacles]]
polygon = [[5, 5], [7, 5], [7, 7], [5, 7]]

[[groups]]
name = "eastbound"
spawn = [[0, 3], [2.5, 3], [2.5, 9], [0, 9]]
count = 25
goal = [[11, 2], [12, 2], [12, 10], [11, 10]]
emotion = { choices = ["happy", "neutral", "angry", "sad"], weights = [3, 3, 2, 2] }

[[groups]]
name = "northbound"
spawn = [[3, 0], [9, 0], [9, 2.5], [3, 2.5]]
count = 25
goal = [[2, 11], [10, 11], [10, 12], [2, 12]]
emotion = { choices = ["happy", "neutral", "angry", "sad"], weights = [3, 3, 2, 2] }
"""
OBSTACLE = shapely.Polygon([[5, 5], [7, 5], [7, 7], [5, 7]])
#: Frames the crossing may take (80 s at 30 fps; the slowest, sad, walk 0.44 m/s).
MAX_FRAMES = 2400
#: Frames of the baseline without avoidance.
BASELINE_FRAMES = 450
#: Closest two hips may come at any frame (metres), and how deep into the obstacle a hip may be.
MIN_HIP_DISTANCE = 0.3
OBSTACLE_TOLERANCE = 0.05


def _export(tmp: Path, toml: str, name: str = "site") -> Any:
    scene = tmp / "square.toml"
    scene.write_text(toml)
    return CliRunner().invoke(app, ["web", "--scene", str(scene), "--out", str(tmp / name)],
                              env={"COLUMNS": "200"})


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    pytest.importorskip("onnx")
    tmp = tmp_path_factory.mktemp("crowd")
    result = _export(tmp, SQUARE)
    assert result.exit_code == 0, result.output
    return tmp / "site", result.output


# --------------------------------------------------------------------------- the export


def test_the_export_writes_the_scene_and_vendors_recast_navigation(exported):
    folder, output = exported
    assert "scene square (scene.json): 2 group(s), 50 agent(s)" in output
    meta = json.loads((folder / "agent.json").read_text())
    assert meta["scene"] == "scene.json"
    doc = json.loads((folder / "scene.json").read_text())
    assert doc["format"] == "emotive-web-scene/1" and doc["name"] == "square"
    assert [g["count"] for g in doc["groups"]] == [25, 25]
    for name in ("core/index.mjs", "generators/index.mjs", "wasm/recast-navigation.wasm.js",
                 "wasm/recast-navigation.wasm.wasm", "LICENSE", "LICENSE-recastnavigation.txt",
                 "VENDOR.md"):
        assert (folder / RECAST / name).is_file(), name
    html = (folder / "index.html").read_text()
    assert '"@recast-navigation/core": "./vendor/recast-navigation/core/index.mjs"' in html


def test_the_walkable_mesh_is_the_area_less_the_obstacle_facing_up(exported):
    doc = json.loads((exported[0] / "scene.json").read_text())
    v = np.asarray(doc["mesh"]["vertices"])
    tri = v[np.asarray(doc["mesh"]["triangles"])]
    a, b = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    # Clockwise in (x, y): with y as the world z, (v1 - v0) x (v2 - v0) points up (+Y).
    assert (cross < 0).all()
    assert -cross.sum() / 2 == pytest.approx(144 - 4, abs=1e-6)
    centres = tri.mean(axis=1)
    assert not shapely.contains_xy(OBSTACLE, centres[:, 0], centres[:, 1]).any()


def test_spawns_goals_and_emotions_are_resolved_as_the_crowd_resolves_them(exported):
    from emotive.crowd.scene import load_scene
    from emotive.crowd.validation import polygon, spawn_sites, walkable_area

    folder = exported[0]
    doc = json.loads((folder / "scene.json").read_text())
    scene = load_scene(folder.parent / "square.toml")
    walkable = walkable_area(scene)
    labels = load_gait_model().labels
    for g, group in zip(doc["groups"], scene.groups, strict=True):
        np.testing.assert_allclose(g["sites"], spawn_sites(polygon(group.spawn, "s"), walkable),
                                   atol=1e-4)
        want = [to_model_schedule(c, labels).at(0.0) for c in group.emotion.choices]
        np.testing.assert_allclose(g["emotion"]["choices"], want, atol=1e-6)
        assert g["emotion"]["p"] == pytest.approx([0.3, 0.3, 0.2, 0.2])
        exit_shape = shapely.Polygon(group.goal.polygon)
        targets = np.asarray(g["goal"]["targets"]).reshape(-1, 3, 2)
        assert shapely.contains_xy(exit_shape, *targets.mean(axis=1).T).all()
    assert doc["scene"] == scene.to_dict()


def test_a_bad_scene_is_one_line_and_writes_nothing(tmp_path):
    bad = SQUARE.replace("spawn = [[0, 3], [2.5, 3], [2.5, 9], [0, 9]]",
                         "spawn = [[5.5, 5.5], [6.5, 5.5], [6.5, 6.5], [5.5, 6.5]]")
    result = _export(tmp_path, bad)
    assert isinstance(result.exception, SceneError), result.output
    message = str(result.exception)
    assert "\n" not in message and "eastbound" in message and "spawn" in message
    assert sorted(p.name for p in tmp_path.iterdir()) == ["square.toml"]


def test_without_a_scene_the_export_names_none(web_export):
    meta = json.loads((web_export.folder / "agent.json").read_text())
    assert "scene" not in meta and not (web_export.folder / "scene.json").exists()


# --------------------------------------------------------------------------- the arithmetic

#: Run by node: crowd-math.js on the cases, printed as JSON.
MATH_SCRIPT = """
import { navigationParams, detourParams, insidePolygon, TriangleSampler, randomSource,
         bodyPathEnd, MAX_TURN, DETOUR } from "./crowd-math.js";
const c = JSON.parse(process.argv[2]);
const params = c.weights.map((w, k) => navigationParams(c.navigation, c.emotion, c.speeds, w,
                                                         c.paces[k]));
const detour = params.map((p) => detourParams(p, c.navigation, true));
const blind = detourParams(params[0], c.navigation, false);
const inside = c.points.map(([x, y]) => insidePolygon(x, y, c.ring));
const sampler = new TriangleSampler(c.triangles);
const rng = randomSource(7);
const samples = Array.from({ length: 400 }, () => sampler.sample(rng));
const ends = c.follow.map((f) => bodyPathEnd(f.here, f.yaw, f.plan, f.speed, 30, f.last));
console.log(JSON.stringify({ params, detour, blind, inside, samples, ends, maxTurn: MAX_TURN,
                             margin: DETOUR.radiusMargin }));
"""


def test_the_pages_crowd_arithmetic_matches_python(tmp_path, exported):
    """navigationParams against navigation_rows (labels, blends, valence/arousal points, a
    pace), the Detour mapping against the engines' table, point-in-polygon against shapely,
    triangle samples inside, and the body's path towards its plan turned at most 15 degrees."""
    node = shutil.which("node")
    require_tool(node is not None, "node is not installed (apt-get install nodejs)")
    for name in ("crowd-math.js", "emotion.js"):
        shutil.copy(PAGE / name, tmp_path / name)
    (tmp_path / "run.mjs").write_text(MATH_SCRIPT)
    folder = exported[0]
    meta = json.loads((folder / "agent.json").read_text())
    doc = json.loads((folder / "scene.json").read_text())
    model = load_gait_model()
    labels = list(model.labels)
    texts = ["happy", "sad", "angry", "neutral", "happy=0.7,neutral=0.3", "sad=0.5,angry=0.5",
             "valence=0.5,arousal=-0.2", "valence=-0.6,arousal=0.7", labels[6]]
    weights = np.array([to_model_schedule(t, labels).at(0.0) for t in texts])
    paces = np.linspace(0.6, 1.4, len(texts))
    rng = np.random.default_rng(0)
    points = rng.uniform(-1, 13, (300, 2))
    ring = [[0, 0], [12, 0], [12, 12], [6, 4], [0, 12]]
    cases = {"navigation": doc["navigation"], "emotion": meta["emotion"],
             "speeds": [meta["navigation"]["rows"][n][0] for n in labels],
             "weights": weights.tolist(), "paces": paces.tolist(), "points": points.tolist(),
             "ring": ring, "triangles": doc["groups"][0]["goal"]["targets"],
             "follow": [{"here": [1, 1], "yaw": 0.0, "plan": plan, "speed": 1.2, "last": last}
                        for plan, last in (([1, 1.02], None), ([1.04, 1], None),
                                           ([1, 1.02], [1, 1.52]), ([1, 1.02], [1, 2]))]}
    run = subprocess.run([node, "run.mjs", json.dumps(cases)], cwd=tmp_path, check=True,
                         capture_output=True, text=True, timeout=120)
    out = json.loads(run.stdout)
    speed = np.asarray(model.controls.speed) * model.fps
    want = navigation_rows(weights, labels, speed, paces)
    columns = ["desired_speed", "radius", "time_gap", "yield_strength", "yield_range"]
    got = np.array([[p[c] for c in columns] for p in out["params"]])
    # agent.json rounds each label's speed to 1e-4 m/s and each point to 1e-4.
    np.testing.assert_allclose(got, want, atol=2e-3)
    # Detour's agent: speed carries over, radius with the tracking margin; separation weight
    # and query range scale as Unreal's (one base each, the same for every emotion).
    bases = []
    for k, d in enumerate(out["detour"]):
        unreal = engine_parameters(navigation_params(weights[k], labels, speed, paces[k]))["unreal"]
        assert d["maxSpeed"] == pytest.approx(unreal["MaxWalkSpeed"] / 100, abs=2e-3)
        radius = d["radius"] - out["margin"]
        assert radius == pytest.approx(unreal["AgentRadius"] / 100, abs=2e-3)
        bases.append([d["separationWeight"] / unreal["CrowdSeparationWeightScale"],
                      d["collisionQueryRange"] / radius / unreal["CrowdCollisionQueryRangeScale"],
                      d["pathOptimizationRange"] / radius])
    np.testing.assert_allclose(bases, np.broadcast_to(bases[0], np.shape(bases)), rtol=5e-3)
    assert 0 < out["margin"] <= 0.1
    # The baseline: no avoidance (2), no separation (4), no neighbours to collide with.
    assert out["blind"]["updateFlags"] & 6 == 0 and out["blind"]["collisionQueryRange"] < 0.01
    np.testing.assert_array_equal(out["inside"], shapely.contains_xy(shapely.Polygon(ring),
                                                                     points[:, 0], points[:, 1]))
    exit_shape = shapely.Polygon(doc["scene"]["groups"][0]["goal"])
    samples = np.asarray(out["samples"])
    assert shapely.contains_xy(exit_shape.buffer(1e-6), samples[:, 0], samples[:, 1]).all()
    # Uniform over the triangles: the samples' mean is the region's centroid.
    tri = np.asarray(doc["groups"][0]["goal"]["targets"]).reshape(-1, 3, 2)
    a, b = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    area = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) / 2
    centroid = (tri.mean(axis=1) * area[:, None]).sum(axis=0) / area.sum()
    np.testing.assert_allclose(samples.mean(axis=0), centroid, atol=0.4)
    ahead, aside, kept, longer = out["ends"]
    # Ahead at 0.6 m/s (0.02 m a frame): a path 0.6 / 1.2 of the gait's 1 m stopping distance.
    assert ahead == pytest.approx([1.0, 1.5], abs=1e-9)
    # A plan to the side: the path turns by 15 degrees this frame, 1 m long (full speed).
    assert out["maxTurn"] == pytest.approx(np.radians(15))
    assert aside == pytest.approx([1 + np.sin(out["maxTurn"]), 1 + np.cos(out["maxTurn"])])
    # The current path already runs that way (within 5 cm of length): kept; else replaced.
    assert kept is None and longer == pytest.approx([1.0, 1.5], abs=1e-9)


# --------------------------------------------------------------------------- in Chromium


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    yield from headless_chromium(HANG_SECONDS)


@pytest.fixture(scope="module")
def served(exported) -> Iterator[str]:
    with static_server(exported[0]) as base:
        yield base


def _crossing(browser: Any, served: str, query: str, max_frames: int = MAX_FRAMES
              ) -> tuple[Any, Any]:
    """The page with the scene, stepped through the hook until done or ``max_frames``."""
    web = open_page(browser, served, query)
    try:
        web.wait("e.ready || e.status === 'error'")
        assert web.hook("e.status") == "running", web.hook("e.error")
        return web, run_crowd(web, max_frames)
    finally:
        web.close()


def _hips_in_obstacle(frames: list[dict[str, Any]]) -> int:
    """Hip samples more than :data:`OBSTACLE_TOLERANCE` inside the obstacle."""
    hips = np.concatenate([np.asarray(r["hips"]).reshape(-1, 2) for r in frames])
    deep = OBSTACLE.buffer(-OBSTACLE_TOLERANCE)
    return int(shapely.contains_xy(deep, hips[:, 0], hips[:, 1]).sum())


def test_fifty_agents_cross_the_square_without_overlap(browser, served):
    """The bodies' hips (read from the page) stay 0.3 m apart at every frame, none walks into
    the obstacle, all 50 reach their exit, and the page fetches nothing off the host."""
    web, run = _crossing(browser, served, "paused=1")
    closest, at, close = closest_hips(run.frames)
    gaps = np.concatenate([np.linalg.norm(
        np.asarray(r["hips"]).reshape(-1, 2) - np.asarray(r["nav"]).reshape(-1, 2), axis=1)[
        np.asarray(r["warm"]) == 0] for r in run.frames])
    s = run.summary
    print(f"crossing: closest hips {closest:.3f} m at frame {at} ({close} pair-frames under "
          f"0.3 m), {s['reached']}/{s['spawned']} reached their exit in {s['frame']} frames, "
          f"body to navigation agent p99 {np.percentile(gaps, 99):.3f} m (max "
          f"{gaps.max():.3f} m), {s['frame'] / run.seconds:.0f} frames/s stepped in the page, "
          f"Detour update median {s['updateMs']} ms, navigation mesh {s['navMeshMs']:.0f} ms")
    assert web.off_host == [] and web.problems == [], (web.off_host, web.problems)
    assert any(u.endswith("recast-navigation.wasm.wasm") for u in web.requests)
    assert s["spawned"] == 50 and len(run.frames) == s["frame"]
    assert closest >= MIN_HIP_DISTANCE, f"hips {closest:.3f} m apart at frame {at}"
    assert _hips_in_obstacle(run.frames) == 0
    assert s["reached"] >= 0.99 * 50, s
    assert s["done"]


def test_without_avoidance_the_bodies_overlap(browser, served):
    """The baseline of the same page (``?avoidance=0``: navigation agents that do not see each
    other) lets hips come closer than 0.3 m, so the test above can fail: 15 s of it, the two
    groups meeting around the obstacle."""
    web, run = _crossing(browser, served, "paused=1&avoidance=0", max_frames=BASELINE_FRAMES)
    closest, at, close = closest_hips(run.frames)
    print(f"without avoidance: closest hips {closest:.3f} m at frame {at}, {close} pair-frames "
          f"under 0.3 m in {run.summary['frame']} frames")
    assert run.summary["avoidance"] is False
    assert closest < MIN_HIP_DISTANCE and close > 0
    assert web.off_host == [] and web.problems == []
