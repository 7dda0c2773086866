"""The glTF reader under hostile input: every mutant of the fuzz corpus is read plausibly or
refused with a one-line MotionFileError naming its element, in a process held to 2 GB of
address space, opening nothing outside its folder, never hanging; and node graphs at and
beyond the limits, one by one, read in time linear in their size."""

from __future__ import annotations

import functools
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from gltf_mutants import (
    ADDRESS_SPACE,
    CHAIN_NODES,
    OUTSIDE,
    SENTINEL,
    base,
    make_outside,
    mutants,
    write_case,
)
from test_gltf_input import glb_file, refused, walk_json
from test_gltf_writer import standing_clip

import emotive
from cli_helpers import run_main
from emotive.io.gltf_read import read_gltf

#: Cases read by one process (each process pays for importing the reader once).
BATCH = 200
#: A worker that has printed nothing new for this many seconds has hung in the case it last
#: started (a case takes well under 5 s of processor time, which each result records; the
#: hardening campaign's worst took 150 s, a FIFO forever). The worker's progress is watched,
#: not the batch's wall time, so a busy machine that runs each case slowly is not a hang.
HANG_S = 120
#: Seconds between looks at the worker's output.
POLL_S = 0.2
#: Processor seconds one case may take.
CASE_CPU_S = 5.0
#: Longest message of a refusal: fixed text, an element, quotes of at most 80 characters and
#: the file's path.
MAX_MESSAGE_CHARS = 600


@functools.cache
def corpus() -> tuple:
    """The corpus, built once for the tests of this module."""
    return tuple(mutants())


def _watch(proc: subprocess.Popen, out: Path) -> str | None:
    """Wait for the worker; kill it if its output stops growing for :data:`HANG_S`."""
    size, quiet = -1, 0.0
    while True:
        try:
            proc.wait(timeout=POLL_S)
            return None
        except subprocess.TimeoutExpired:
            now = out.stat().st_size
            quiet = 0.0 if now != size else quiet + POLL_S
            size = now
            if quiet >= HANG_S:
                proc.kill()
                proc.wait()
                return "timeout"


def _run_batch(cases: list[dict], warmup: str, folder: Path) -> tuple[list[dict], str | None]:
    """Results of reading ``cases`` in one worker process, and the case it hung in."""
    listing = folder / "batch.json"
    listing.write_text(json.dumps({
        "cases": cases, "warmup": warmup,
        "trusted": [str(Path(emotive.__file__).resolve().parents[1])]}))
    here = Path(__file__).resolve().parent
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(here), str(here.parent), os.environ.get("PYTHONPATH", "")]),
        "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    out = folder / "batch.out"
    with open(out, "wb") as sink:
        proc = subprocess.Popen([sys.executable, str(here / "gltf_mutants.py"), str(listing)],
                                stdin=subprocess.DEVNULL, stdout=sink,
                                stderr=subprocess.STDOUT, env=env)
        hung = _watch(proc, out)
    results, started = [], None
    for line in out.read_text(errors="replace").splitlines():
        if not line.startswith("{"):
            continue
        record = json.loads(line)
        if "start" in record:
            started = record["start"]
        else:
            results.append(record)
            started = None
    if started is not None:
        hung = started
    elif proc.returncode != 0 and hung is None:
        hung = f"worker exit {proc.returncode}: {out.read_text(errors='replace')[-800:]}"
    return results, hung


@pytest.fixture(scope="module")
def fuzz(tmp_path_factory):
    """``(corpus by name, result by name, hangs)`` of reading every mutant once."""
    root = tmp_path_factory.mktemp("gltf_fuzz")
    _, blob = base()
    outside = make_outside(root / OUTSIDE, blob)
    by_name = {m.name: m for m in corpus()}
    cases = []
    for mutant in by_name.values():
        folder = root / "cases" / mutant.name
        path = write_case(mutant, folder, outside)
        cases.append({"name": mutant.name, "path": str(path), "folder": str(folder)})
    warmup = str(root / "cases" / "base_glb" / "walk.glb")
    results, hangs, todo = {}, [], cases
    while todo:
        batch, todo = todo[:BATCH], todo[BATCH:]
        done, hung = _run_batch(batch, warmup, root)
        results.update((r["name"], r) for r in done)
        if hung is not None:
            hangs.append(hung)
            # The cases after the one that hung still get read.
            finished = {r["name"] for r in done} | {hung}
            todo = [c for c in batch if c["name"] not in finished] + todo
    return by_name, results, hangs


def test_corpus_is_large_deterministic_and_covers_the_campaign():
    first = corpus()
    names = [m.name for m in first]
    assert len(first) >= 600 and len(set(names)) == len(names)
    again = mutants()
    assert [(m.name, m.json, m.raw) for m in again] == [(m.name, m.json, m.raw) for m in first]
    for family in ("escape_bin", "escape_glb", "link_", "fifo_buffer", "main_fifo", "main_zero",
                   "zeros_", "size_accessors0_count", "node0_matrix", "sample_translation",
                   "chain_campaign", "crowd_most", "flip_", "swap_"):
        assert any(n.startswith(family) for n in names), family
    chain = next(m for m in first if m.name == "chain_campaign")
    assert len(chain.json["nodes"]) == CHAIN_NODES


def test_no_case_hangs_or_crashes(fuzz):
    by_name, results, hangs = fuzz
    assert hangs == []
    assert set(results) == set(by_name)
    crashes = [f"{r['name']}: {r['message']}" for r in results.values()
               if r["outcome"] == "crash"]
    # MemoryError under the 2 GB address-space limit would be a crash too.
    assert crashes == [], crashes[:10]
    # Each case's own processor time (not the wall clock, which a busy machine stretches).
    slow = {n: round(r["cpu_s"], 2) for n, r in results.items() if r["cpu_s"] > CASE_CPU_S}
    assert slow == {}


def test_no_case_opens_a_file_outside_its_folder(fuzz):
    by_name, results, _ = fuzz
    opened = {n: r["outside"] for n, r in results.items() if r["outside"]}
    assert opened == {}
    escaped = [n for n in by_name if n.startswith(("escape_", "link_"))]
    assert len(escaped) > 100
    # The sentinel beside each case folder is a valid buffer: a reader that followed the
    # reference would have built a motion.
    assert [n for n in escaped if results[n]["outcome"] != "refused"] == []


def test_each_refusal_is_one_line_naming_the_file_and_the_element(fuzz):
    by_name, results, _ = fuzz
    wrong = []
    for name, result in results.items():
        mutant, message = by_name[name], result["message"]
        if result["outcome"] != "refused":
            continue
        if ("\n" in message or len(message) > MAX_MESSAGE_CHARS
                or not message.startswith(f"{result['path']}: ")
                or "malformed field" in message):
            wrong.append(f"{name}: {message[:300]}")
        elif mutant.expect not in ("any", "read") and mutant.expect not in message:
            wrong.append(f"{name} (wants {mutant.expect!r}): {message[:300]}")
    assert wrong == [], wrong[:10]


def test_cases_that_must_be_read_are_and_every_read_is_plausible(fuzz):
    by_name, results, _ = fuzz
    unread = [f"{n}: {r['message'][:200]}" for n, r in results.items()
              if by_name[n].expect == "read" and r["outcome"] != "read"]
    assert unread == []
    implausible = [n for n, r in results.items() if r["outcome"] == "read"
                   and not r["plausible"]]
    assert implausible == []
    outcomes = [r["outcome"] for r in results.values()]
    assert outcomes.count("read") > 100 and outcomes.count("refused") > 400


def test_the_corpus_runs_in_a_bounded_process(fuzz):
    """The limit the worker sets: 2 GB, so a huge declared count would end in MemoryError."""
    assert ADDRESS_SPACE == 2 * 1024**3
    _, results, _ = fuzz
    assert results["chain_campaign"]["outcome"] == "refused"
    assert "100,023" in results["chain_campaign"]["message"]
    assert results["crowd_most"]["outcome"] == "read"
    assert results["chain_deepest"]["outcome"] == "read"


CLI_SAMPLE = ("escape_bin_0", "escape_bin_2", "escape_glb_3", "link_0", "link_2",
              "node0_matrix_0", "sample_translation_0", "zeros_0", "graph_cycle", "base_glb")


def test_cli_prints_one_error_line_for_escapes_and_bad_values(monkeypatch, capsys, tmp_path):
    by_name = {m.name: m for m in corpus()}
    _, blob = base()
    outside = make_outside(tmp_path / OUTSIDE, blob)
    assert (outside / SENTINEL).read_bytes() == blob
    monkeypatch.chdir(tmp_path)
    for name in CLI_SAMPLE:
        path = write_case(by_name[name], tmp_path / "cases" / name, outside)
        code, out, err = run_main(monkeypatch, capsys, "info", path)
        assert "Traceback" not in out + err, (name, err)
        if name == "base_glb":
            assert code == 0, err
            continue
        assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, (name, err)


# --- Node graphs at and beyond the limits, one by one ------------------------------------


def _chain(root: dict, extra: int, crowd: int = 0) -> dict:
    """``root`` with its skeleton under a chain of ``extra`` nodes and ``crowd`` loose ones."""
    root = json.loads(json.dumps(root))
    first = len(root["nodes"])
    root["nodes"] += [{"children": [first + k + 1]} for k in range(extra - 1)]
    root["nodes"].append({"children": [0]})
    root["nodes"] += [{"name": f"prop{k}"} for k in range(crowd)]
    root["scenes"][0]["nodes"] = [first]
    return root


def test_the_campaigns_100k_node_chain_is_refused_by_its_node_count(tmp_path):
    root, blob = walk_json()
    extra = 100_023 - len(root["nodes"])
    path = glb_file(tmp_path, _chain(root, extra), blob)
    refused(path, "nodes: holds 100,023 entries: at most 65,536 are read")


def test_a_chain_at_the_depth_limit_reads_and_one_deeper_is_refused(tmp_path):
    from emotive.io import input_limits as limits

    root, blob = walk_json()
    own = 6  # Hips, Spine, Chest, UpperArm, LowerArm, Hand
    back = read_gltf(glb_file(tmp_path, _chain(root, limits.MAX_DEPTH - own), blob))
    assert back.skeleton.names == standing_clip().skeleton.names
    refused(glb_file(tmp_path, _chain(root, limits.MAX_DEPTH - own + 1), blob, "deeper.glb"),
             f"is nested {limits.MAX_DEPTH + 1:,} nodes deep: at most {limits.MAX_DEPTH:,}")


def test_a_scene_at_the_node_limit_reads(tmp_path):
    from emotive.io import input_limits as limits

    root, blob = walk_json()
    crowd = limits.MAX_NODES - len(root["nodes"]) - 1
    back = read_gltf(glb_file(tmp_path, _chain(root, 1, crowd), blob))
    assert back.num_frames == 4


def _lines_run(path: Path) -> int:
    """Lines of the glTF reader's own modules executed while reading ``path``."""
    folder = str(Path(read_gltf.__code__.co_filename).parent)
    count = 0

    def local(frame, event, arg):
        nonlocal count
        if event == "line":
            count += 1
        return local

    def calls(frame, event, arg):
        name = frame.f_code.co_filename
        if name.startswith(folder) and ("gltf_" in name or "input_limits" in name):
            return local
        return None

    sys.settrace(calls)
    try:
        read_gltf(path)
    finally:
        sys.settrace(None)
    return count


def _animated_chain(joints: int) -> tuple[dict, bytes]:
    """A file without skin: a chain of ``joints`` nodes whose top and bottom nodes turn, so
    every node of the chain is a joint."""
    blob = np.array([0.0, 1.0, 0, 0, 0, 1, 0, 0.3826834, 0, 0.9238795],
                    dtype="<f4").tobytes()
    root = {
        "asset": {"version": "2.0"}, "buffers": [{"byteLength": len(blob)}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 8},
                        {"buffer": 0, "byteOffset": 8, "byteLength": 32}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 2, "type": "SCALAR"},
                      {"bufferView": 1, "componentType": 5126, "count": 2, "type": "VEC4"}],
        "nodes": [{"name": f"j{k}", "translation": [0, 0.001, 0],
                   **({"children": [k + 1]} if k + 1 < joints else {})} for k in range(joints)],
        "animations": [{"samplers": [{"input": 0, "output": 1}],
                        "channels": [{"sampler": 0, "target": {"node": n, "path": "rotation"}}
                                     for n in (0, joints - 1)]}]}
    return root, blob


def test_node_trees_are_read_in_time_linear_in_their_size(tmp_path):
    """Quadratic work (each node's ancestors listed, a parent searched among all nodes) shows
    as lines run growing 16 times when the tree grows 4 times; linear work grows 4 times."""
    root, blob = walk_json()
    small = _lines_run(glb_file(tmp_path, _chain(root, 300, 700), blob, "small.glb"))
    large = _lines_run(glb_file(tmp_path, _chain(root, 1200, 2800), blob, "large.glb"))
    assert large / small < 5.0, (small, large)
    assert (large - small) / 3000 < 100, (small, large)
    # Without a skin every node of an animated chain is a joint: joints grow with the tree.
    few = _lines_run(glb_file(tmp_path, *_animated_chain(200), "few.glb"))
    many = _lines_run(glb_file(tmp_path, *_animated_chain(800), "many.glb"))
    assert many / few < 5.0, (few, many)
    assert read_gltf(tmp_path / "many.glb").skeleton.num_joints == 800
