"""Flow beside experiments: a door's specific flow and a corridor's speed-density relation.

Legend: ``N`` agents who cross the line, ``F`` frames, ``K`` flow windows.

Reads a run folder that ``emotive crowd`` wrote (``trajectories.csv``, PedPy's text format,
and ``scene.json``) and measures it with PedPy's own functions (PedPy is the Python port of
JPSreport, the analysis tool of JuPedSim's project), not with hand-written counting:

* **line** (a door): PedPy's N-t diagram (``compute_n_t``: the frame each agent first crosses
  the line) and flow (``compute_flow``: persons crossing in a window over the time between
  the last crossings of consecutive windows, in 1/s). Reported over the whole passage (one
  window from the first crossing to the last) and as the mean over the *steady* windows of
  ``window`` seconds: all but the first (the door filling: PedPy counts its first person
  with no time before it) and the last (the stragglers). The specific flow is the flow
  divided by the line's length, in persons per metre per second, (m s)^-1.
* **area** (a stretch of corridor): the density per frame (``compute_classic_density``:
  agents inside over the area; or ``compute_voronoi_density`` over
  ``compute_individual_voronoi_polygons`` in the walkable area) and the speed per frame
  (``compute_mean_speed_per_frame``; with Voronoi density ``compute_voronoi_speed``, the
  speed weighted by each cell's share of the area), from ``compute_individual_speed`` over
  +-0.5 s (one stride, so that the hips' sideways sway cancels). Frames with a density and a
  speed (classic: an agent inside; Voronoi: a cell reaching into the area) are binned by density
  (:data:`DENSITY_BIN` wide), each bin beside Weidmann's fundamental diagram
  (:func:`weidmann_speed`).

The scene file names no measurement places (the narrowest gap of an area is not generally
knowable), so ``--line`` and ``--area`` are given on the command line; docs/crowd.md lists
them for the example scenes. Writes ``flow.json`` into the run folder (atomically).

Run as ``python -m emotive.crowd.flow OUT [--line x0,y0,x1,y1] [--area x0,y0,x1,y1,...]
[--window S] [--density classic|voronoi]``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
from shapely.geometry import LineString, Polygon

from emotive.crowd.errors import CrowdError
from emotive.errors import EmotiveError
from emotive.io.atomic import atomic_output

__all__ = ["DENSITY_BIN", "WEIDMANN", "area_speed_density", "import_pedpy", "line_flow",
           "load_run", "measure_flow", "parse_area", "parse_line", "report", "weidmann_speed",
           "write_flow"]

#: Weidmann's fundamental diagram (Weidmann 1993; the values commonly quoted, see docs/crowd.md
#: for what could be verified): free speed ``v0`` (m/s), ``gamma`` (m^-2) and the jam density
#: ``rho_max`` (m^-2).
WEIDMANN = {"v0": 1.34, "gamma": 1.913, "rho_max": 5.4}
#: Width of the density bins of the speed-density table (m^-2).
DENSITY_BIN = 0.25
#: Default length (s) of the flow windows.
WINDOW = 5.0
#: Half the time (s) over which an agent's speed is taken (PedPy's ``frame_step``).
SPEED_HALF_WINDOW = 0.5
#: How far (m) a line or area may reach past the walkable area (rounding, lines on walls).
SCENE_TOLERANCE = 1e-6
#: Density methods of the area measure.
DENSITY_METHODS = ("classic", "voronoi")


def import_pedpy() -> Any:
    """The ``pedpy`` module.

    Raises:
        CrowdError: it is not installed (naming the extra to install).
    """
    try:
        import pedpy  # noqa: PLC0415 (optional: the crowd extra)
    except ImportError:
        raise CrowdError("flow measures need PedPy: pip install 'emotive[crowd]'") from None
    return pedpy


def weidmann_speed(density: np.ndarray | float, v0: float = WEIDMANN["v0"],
                   gamma: float = WEIDMANN["gamma"],
                   rho_max: float = WEIDMANN["rho_max"]) -> np.ndarray:
    """Weidmann's speed at a density: ``v0 * (1 - exp(-gamma * (1/rho - 1/rho_max)))``.

    Args:
        density: densities (m^-2), any shape.
        v0: free walking speed (m/s).
        gamma: fit parameter (m^-2).
        rho_max: jam density (m^-2), where the speed reaches 0.

    Returns:
        Speeds (m/s), the shape of ``density``: ``v0`` at density 0, 0 from ``rho_max`` on.
    """
    rho = np.asarray(density, dtype=np.float64)
    with np.errstate(divide="ignore"):
        v = v0 * (1.0 - np.exp(-gamma * (1.0 / rho - 1.0 / rho_max)))
    return np.clip(np.where(rho > 0, v, v0), 0.0, v0)


def _numbers(text: str, option: str) -> list[float]:
    try:
        values = [float(v) for v in text.replace(" ", "").split(",")]
    except ValueError:
        raise CrowdError(f"{option} {text!r}: not a list of numbers; write x0,y0,x1,y1,... "
                         "in metres") from None
    if not all(math.isfinite(v) for v in values):
        raise CrowdError(f"{option} {text!r}: a number is not finite; give coordinates in "
                         "metres")
    return values


def parse_line(text: str) -> tuple[tuple[float, float], tuple[float, float]]:
    """The measurement line of ``--line x0,y0,x1,y1`` (metres, the scene's coordinates).

    Raises:
        CrowdError: not four numbers, or both ends at one point.
    """
    v = _numbers(text, "--line")
    if len(v) != 4:
        raise CrowdError(f"--line {text!r}: needs 4 numbers x0,y0,x1,y1 (its two ends), got "
                         f"{len(v)}")
    a, b = (v[0], v[1]), (v[2], v[3])
    if a == b:
        raise CrowdError(f"--line {text!r}: both ends are the same point; give a line across "
                         "the way, e.g. the door's two posts")
    return a, b


def parse_area(text: str) -> tuple[tuple[float, float], ...]:
    """The measurement area of ``--area x0,y0,x1,y1,x2,y2,...`` (a convex polygon, metres).

    Raises:
        CrowdError: an odd count, under three corners, no area or not convex.
    """
    v = _numbers(text, "--area")
    if len(v) % 2 or len(v) < 6:
        raise CrowdError(f"--area {text!r}: needs at least 3 corners as x,y pairs "
                         f"(6 or more numbers, an even count), got {len(v)} numbers")
    points = tuple(zip(v[::2], v[1::2], strict=True))
    poly = Polygon(points)
    if not poly.is_valid or poly.area <= 0:
        raise CrowdError(f"--area {text!r}: the corners enclose no area or cross; list them "
                         "in order around the area")
    if poly.convex_hull.area - poly.area > 1e-9 * max(poly.area, 1.0):
        raise CrowdError(f"--area {text!r}: the area is not convex (PedPy measures convex "
                         "areas only); split it or give its convex part")
    return points


def load_run(folder: str | Path) -> tuple[Any, Polygon | None]:
    """A run folder's trajectories (PedPy's ``TrajectoryData``) and walkable area.

    Args:
        folder: the ``--out`` folder of ``emotive crowd`` (``trajectories.csv``; its
            ``scene.json`` gives the walkable area, ``None`` when it has none).

    Raises:
        CrowdError: a missing folder or file, or a file PedPy cannot read.
    """
    pedpy = import_pedpy()
    folder = Path(folder)
    if not folder.is_dir():
        raise CrowdError(f"{folder}: no such folder; give the --out folder of an "
                         "`emotive crowd` run")
    path = folder / "trajectories.csv"
    if not path.is_file():
        raise CrowdError(f"{path}: not found; give the folder an `emotive crowd` run wrote "
                         "(it holds trajectories.csv)")
    try:
        traj = pedpy.load_trajectory_from_txt(trajectory_file=path)
    except (pedpy.errors.PedPyError, ValueError) as exc:
        problem = " ".join(str(exc).split())
        raise CrowdError(f"{path}: PedPy cannot read it ({problem}); rerun `emotive crowd` "
                         "to write it again") from None
    if traj.data.empty:
        raise CrowdError(f"{path}: holds no agent; run a scene with agents")
    scene_path = folder / "scene.json"
    if not scene_path.is_file():
        return traj, None
    try:
        area = json.loads(scene_path.read_text(encoding="utf-8"))["area"]
        walkable = Polygon(area["polygon"], [o["polygon"] for o in area.get("obstacles", [])])
    except (ValueError, KeyError, TypeError) as exc:
        raise CrowdError(f"{scene_path}: not a scene `emotive crowd` wrote ({exc}); rerun the "
                         "run or remove the file") from None
    return traj, walkable


def _inside(walkable: Polygon | None, shape: Any, option: str, text: str) -> None:
    if walkable is not None and not walkable.buffer(SCENE_TOLERANCE).covers(shape):
        raise CrowdError(f"{option} {text}: lies outside the scene's walkable area "
                         "(scene.json: the [area] polygon less its obstacles); give "
                         "coordinates inside it")


def _fmt(points: Any) -> str:
    return ",".join(f"{c:g}" for p in points for c in p)


def _speed(traj: Any) -> Any:
    pedpy = import_pedpy()
    step = max(1, round(SPEED_HALF_WINDOW * traj.frame_rate))
    return pedpy.compute_individual_speed(
        traj_data=traj, frame_step=step,
        speed_calculation=pedpy.SpeedCalculation.BORDER_SINGLE_SIDED)


def line_flow(traj: Any, line: tuple[tuple[float, float], tuple[float, float]],
              window: float = WINDOW, speed: Any = None) -> dict[str, Any]:
    """Flow and specific flow through a measurement line (see the module docstring).

    Args:
        traj: PedPy's ``TrajectoryData``.
        line: the line's two ends ``((x0, y0), (x1, y1))`` (m).
        window: length of the flow windows (s).
        speed: ``compute_individual_speed``'s table, when already computed.

    Returns:
        ``length`` (m), ``crossed`` (N), ``crossings`` (``[id, frame]`` by frame), ``n_t``
        (``[time s, cumulative count]`` at each frame someone crosses), ``first`` and
        ``last`` crossing times (s), ``flow`` and ``specific_flow`` over the whole passage,
        ``windows`` (``K`` rows ``flow``, ``mean_speed``), ``steady_windows``,
        ``steady_flow`` and ``steady_specific_flow`` (``None`` where too few agents
        crossed: one for a flow, windows 2 to K-1 for the steady part).

    Raises:
        CrowdError: no one crosses the line.
    """
    pedpy = import_pedpy()
    if window <= 0:
        raise CrowdError(f"--window {window:g}: must be positive; give seconds, e.g. 5")
    length = float(math.dist(*line))
    nt, crossing = pedpy.compute_n_t(traj_data=traj,
                                     measurement_line=pedpy.MeasurementLine(list(line)))
    if crossing.empty:
        raise CrowdError(f"--line {_fmt(line)}: no one crosses it; put the line across the "
                         "way the agents walk (e.g. between a door's posts)")
    fps = float(traj.frame_rate)
    speed = _speed(traj) if speed is None else speed
    frames = crossing["frame"].to_numpy()
    first, last, end = int(frames.min()), int(frames.max()), int(nt["frame"].max())
    # compute_flow closes a window only before the last frame: a crossing on the final frame
    # of the run is left out of the overall flow.
    span = min(last, end - 1) - first
    overall = None
    if span >= 1:
        whole = pedpy.compute_flow(nt=nt, crossing_frames=crossing, individual_speed=speed,
                                   delta_frame=span, frame_rate=fps)
        overall = float(whole["flow"].iloc[0]) if len(whole) else None
    rows = pedpy.compute_flow(nt=nt, crossing_frames=crossing, individual_speed=speed,
                              delta_frame=max(1, round(window * fps)), frame_rate=fps)
    flows = rows["flow"].to_numpy() if len(rows) else np.zeros(0)  # no columns when empty
    steady = flows[1:-1]
    steady_flow = float(steady.mean()) if len(steady) else None
    steps = nt[nt["cumulative_pedestrians"].diff().fillna(nt["cumulative_pedestrians"]) > 0]
    return {
        "line": [list(p) for p in line], "length": length, "crossed": len(crossing),
        "crossings": crossing[["id", "frame"]].astype(int).to_numpy().tolist(),
        "n_t": [[float(t), int(n)] for t, n in zip(steps["time"], steps[
            "cumulative_pedestrians"], strict=True)],
        "first": first / fps, "last": last / fps,
        "flow": overall, "specific_flow": None if overall is None else overall / length,
        "window": window,
        "windows": [{"flow": float(f), "mean_speed": None if math.isnan(v) else float(v)}
                    for f, v in zip(rows["flow"], rows["mean_speed"], strict=True)]
        if len(rows) else [],
        "steady_windows": len(steady), "steady_flow": steady_flow,
        "steady_specific_flow": None if steady_flow is None else steady_flow / length,
    }


def area_speed_density(traj: Any, area: tuple[tuple[float, float], ...],
                       density: str = "classic", walkable: Polygon | None = None,
                       speed: Any = None) -> dict[str, Any]:
    """Density and speed per frame in a measurement area, binned beside Weidmann's diagram.

    Args:
        traj: PedPy's ``TrajectoryData``.
        area: the convex area's corners (m).
        density: ``"classic"`` (agents inside over the area, arithmetic mean speed) or
            ``"voronoi"`` (Voronoi density and speed; needs ``walkable``).
        walkable: the walkable area (``scene.json``), the Voronoi cells' bound.
        speed: ``compute_individual_speed``'s table, when already computed.

    Returns:
        ``area`` (the corners), ``size`` (m^2), ``density_method``, ``frames`` (F, with a
        density and a speed: classic, an agent inside; Voronoi, a cell reaching in),
        ``mean_density`` (m^-2), ``mean_speed`` (m/s), ``bins``: per density bin
        ``from``/``to`` (m^-2), ``frames``, ``density``, ``speed`` (mean) and
        ``speed_sd`` (m/s), ``specific_flow`` (mean density times speed, (m s)^-1) and
        ``weidmann_speed`` (m/s, at the bin's mean density).

    Raises:
        CrowdError: an unknown method, Voronoi without a walkable area, or no agent ever in
            the area.
    """
    pedpy = import_pedpy()
    if density not in DENSITY_METHODS:
        raise CrowdError(f"--density {density!r}: unknown; choose one of "
                         f"{', '.join(DENSITY_METHODS)}")
    measurement = pedpy.MeasurementArea(list(area))
    speed = _speed(traj) if speed is None else speed
    if density == "classic":
        rho = pedpy.compute_classic_density(traj_data=traj, measurement_area=measurement)
        v = pedpy.compute_mean_speed_per_frame(traj_data=traj, individual_speed=speed,
                                               measurement_area=measurement)
    else:
        if walkable is None:
            raise CrowdError("--density voronoi: needs the run's scene.json (the walkable "
                             "area bounds the cells); use --density classic or add it")
        cells = pedpy.compute_individual_voronoi_polygons(
            traj_data=traj, walkable_area=pedpy.WalkableArea(
                list(walkable.exterior.coords), [list(r.coords) for r in walkable.interiors]))
        rho, intersection = pedpy.compute_voronoi_density(individual_voronoi_data=cells,
                                                          measurement_area=measurement)
        v = pedpy.compute_voronoi_speed(traj_data=traj, individual_speed=speed,
                                        individual_voronoi_intersection=intersection,
                                        measurement_area=measurement)
    table = rho.merge(v, on="frame")
    table = table[(table["density"] > 0) & table["speed"].notna()]
    if table.empty:
        raise CrowdError(f"--area {_fmt(area)}: no agent is ever inside it; put it where the "
                         "agents walk (e.g. the middle of the corridor)")
    table = table.assign(bin=np.floor(table["density"] / DENSITY_BIN).astype(int),
                         flow=table["density"] * table["speed"])
    bins = []
    for k, group in table.groupby("bin"):
        mean_rho = float(group["density"].mean())
        bins.append({"from": k * DENSITY_BIN, "to": (k + 1) * DENSITY_BIN,
                     "frames": len(group), "density": mean_rho,
                     "speed": float(group["speed"].mean()),
                     "speed_sd": float(group["speed"].std(ddof=0)),
                     "specific_flow": float(group["flow"].mean()),
                     "weidmann_speed": float(weidmann_speed(mean_rho))})
    return {"area": [list(p) for p in area], "size": float(Polygon(area).area),
            "density_method": density, "frames": len(table),
            "mean_density": float(table["density"].mean()),
            "mean_speed": float(table["speed"].mean()), "bins": bins}


def measure_flow(folder: str | Path, line: str | None = None, area: str | None = None,
                 window: float = WINDOW, density: str = "classic") -> dict[str, Any]:
    """The line and area measures of a run folder (writes nothing).

    Args:
        folder: the run folder.
        line: ``--line``'s text ``x0,y0,x1,y1``, or ``None``.
        area: ``--area``'s text ``x0,y0,x1,y1,x2,y2,...``, or ``None``.
        window: length of the flow windows (s).
        density: ``"classic"`` or ``"voronoi"``.

    Returns:
        ``folder``, ``fps``, ``agents``, ``weidmann`` (the parameters) and ``line`` (see
        :func:`line_flow`) and/or ``area`` (see :func:`area_speed_density`).

    Raises:
        CrowdError: neither given, a bad option, a missing file, a line no one crosses, an
            area outside the scene or never entered.
    """
    pedpy = import_pedpy()
    if line is None and area is None:
        raise CrowdError(f"{folder}: say where to measure: --line x0,y0,x1,y1 (e.g. a door) "
                         "and/or --area x0,y0,x1,y1,x2,y2,... (e.g. a stretch of corridor); "
                         "the scene names none")
    segment = parse_line(line) if line is not None else None
    corners = parse_area(area) if area is not None else None
    traj, walkable = load_run(folder)
    out: dict[str, Any] = {"folder": str(folder), "fps": float(traj.frame_rate),
                           "agents": int(traj.data["id"].nunique()), "weidmann": WEIDMANN}
    try:
        speed = _speed(traj)
        if segment is not None:
            _inside(walkable, LineString(segment), "--line", line)
            out["line"] = line_flow(traj, segment, window, speed)
        if corners is not None:
            _inside(walkable, Polygon(corners), "--area", area)
            out["area"] = area_speed_density(traj, corners, density, walkable, speed)
    except pedpy.errors.PedPyError as exc:
        problem = " ".join(str(exc).split())
        raise CrowdError(f"{folder}: PedPy refused the measurement ({problem}); check "
                         "--line/--area against the scene") from None
    return out


def write_flow(folder: str | Path, result: dict[str, Any]) -> Path:
    """Write ``result`` as ``flow.json`` into the run folder, atomically; return its path."""
    path = Path(folder) / "flow.json"
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(result, indent=1) + "\n", encoding="utf-8")
    return path


def _num(value: float | None, digits: int = 2) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def report(result: dict[str, Any]) -> str:
    """The measures as a readable table (what ``main`` prints)."""
    lines = [f"{result['folder']}: {result['agents']} agents, {result['fps']:g} fps"]
    if "line" in result:
        f = result["line"]
        lines += [
            f"line {_fmt(f['line'])} ({f['length']:.2f} m): {f['crossed']} crossed, from "
            f"{f['first']:.1f} s to {f['last']:.1f} s",
            f"  steady ({f['steady_windows']} windows of {f['window']:g} s): specific flow "
            f"{_num(f['steady_specific_flow'])} (m s)^-1, flow {_num(f['steady_flow'])} 1/s",
            f"  overall (first to last crossing): specific flow {_num(f['specific_flow'])} "
            f"(m s)^-1, flow {_num(f['flow'])} 1/s"]
    if "area" in result:
        a = result["area"]
        w = result["weidmann"]
        lines += [
            f"area {_fmt(a['area'])} ({a['size']:.1f} m^2, {a['density_method']} density): "
            f"{a['frames']} frames measured, mean {a['mean_density']:.2f} m^-2 at "
            f"{a['mean_speed']:.2f} m/s",
            f"  {'density m^-2':>14} {'frames':>7} {'mean':>6} {'speed m/s':>10} {'sd':>5} "
            f"{'Weidmann':>9} {'Js (m s)^-1':>12}"]
        lines += [f"  {b['from']:6.2f}-{b['to']:<7.2f} {b['frames']:7d} {b['density']:6.2f} "
                  f"{b['speed']:10.2f} {b['speed_sd']:5.2f} {b['weidmann_speed']:9.2f} "
                  f"{b['specific_flow']:12.2f}" for b in a["bins"]]
        lines.append(f"  Weidmann: v0 {w['v0']} m/s, gamma {w['gamma']} m^-2, rho_max "
                     f"{w['rho_max']} m^-2")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Measure a run folder, print the table and write ``flow.json``; 2 on a user error."""
    parser = argparse.ArgumentParser(
        prog="python -m emotive.crowd.flow",
        description="A door's specific flow and a corridor's speed-density relation of an "
                    "`emotive crowd` run, computed with PedPy (see docs/crowd.md).")
    parser.add_argument("out", type=Path, help="the run folder (emotive crowd --out)")
    parser.add_argument("--line", help="measurement line x0,y0,x1,y1 in metres (a door); "
                        "write --line=-1,... when the first number is negative")
    parser.add_argument("--area", help="convex measurement area x0,y0,x1,y1,x2,y2,... in "
                        "metres; write --area=-1,... when the first number is negative")
    parser.add_argument("--window", type=float, default=WINDOW,
                        help=f"flow window in seconds (default {WINDOW:g})")
    parser.add_argument("--density", choices=DENSITY_METHODS, default="classic",
                        help="density method of the area (default classic)")
    args = parser.parse_args(argv)
    try:
        result = measure_flow(args.out, args.line, args.area, args.window, args.density)
        path = write_flow(args.out, result)
    except EmotiveError as exc:
        print(f"error: {' '.join(str(exc).splitlines())}", file=sys.stderr)
        return 2
    print(report(result))
    print(f"wrote {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
