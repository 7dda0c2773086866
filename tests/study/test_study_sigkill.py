"""No acknowledged response is lost when the study server is killed with SIGKILL mid-study,
on SQLite and on PostgreSQL; then the analysis of the whole study.

The server (``emotive study serve``) and 30 concurrent simulated participants
(``emotive study simulate``) run as separate processes, as a user runs them. Once the server
has stored responses, it is killed with SIGKILL; the simulation waits for it until its
``--deadline``, then prints its summary and gives up in one error line. A new server on the
same database takes 10 more participants. The export must then hold every submission the
server acknowledged exactly once (the receipts each simulation wrote after a confirmation),
plus at most the submissions that were in flight at the kill, and ``analyze`` must report the
Anderson-Darling test and flag the careless raters.

Waits are on observable state (printed URLs, the health counter, process exits); wall time
only bounds a hang.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import httpx
import pytest

#: Wall seconds any one wait may take (a hang guard, not a budget).
HANG_SECONDS = 300.0
#: Stored values at which the server is killed (30 participants store 600 in all).
KILL_AFTER = 120
#: Seconds the first simulation waits for the killed server (its ``--deadline``).
DEADLINE = 3.0
#: The command line of emotive, in this interpreter.
EMOTIVE = [sys.executable, "-c", "from emotive.cli import main; main()"]

pytestmark = pytest.mark.slow


def _serve(folder: Path, db_url: str | None, log: Path) -> tuple[subprocess.Popen, str]:
    cmd = [*EMOTIVE, "study", "serve", str(folder), "--port", "0"]
    if db_url:
        cmd += ["--db", db_url]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=log.open("ab"), text=True)
    deadline = time.monotonic() + HANG_SECONDS
    assert proc.stdout is not None
    for line in proc.stdout:
        if "participants:" in line:
            return proc, line.split("participants:", 1)[1].strip().rstrip("/")
        assert time.monotonic() < deadline, "the server printed no URL"
    raise AssertionError(f"the server stopped before serving: {log.read_text()[-2000:]}")


def _simulate(folder: Path, url: str, n: int, seed: int, receipts: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [*EMOTIVE, "study", "simulate", str(folder), "--url", url, "--participants", str(n),
         "--concurrency", str(n), "--seed", str(seed), "--careless", "0.2",
         "--receipts", str(receipts), "--deadline", str(DEADLINE)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _stored(url: str) -> int:
    try:
        return httpx.get(f"{url}/api/health", timeout=30).json()["responses"]
    except httpx.HTTPError:
        return -1


def _summary(proc: subprocess.Popen, code: int = 0) -> dict:
    out, err = proc.communicate(timeout=HANG_SECONDS)
    assert proc.returncode == code, err[-3000:]
    assert "Traceback" not in err, err[-3000:]
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    assert len(errors) == (code != 0), err[-3000:]
    return json.loads(out.strip().splitlines()[-1])


def _receipts(path: Path) -> list[tuple[str, int, str]]:
    out = []
    for line in path.read_text().splitlines():
        r = json.loads(line)
        out += [(r["participant"], int(r["item"]), name) for name in r["values"]]
    return out


def test_sigkill_mid_study_loses_no_acknowledged_response(study_folder, db_url, tmp_path):
    toml = study_folder / "study.toml"
    toml.write_text(toml.read_text().replace("submit_per_second = 5.0",
                                             "submit_per_second = 1000.0"))
    log = tmp_path / "server.log"
    server, url = _serve(study_folder, db_url, log)
    first = _simulate(study_folder, url, 30, 1, tmp_path / "r1.jsonl")
    deadline = time.monotonic() + HANG_SECONDS
    while _stored(url) < KILL_AFTER:
        assert first.poll() is None, "the simulation ended before the kill"
        assert time.monotonic() < deadline, "the server stored too little"
    server.send_signal(signal.SIGKILL)
    server.wait(HANG_SECONDS)
    one = _summary(first, code=2)  # gave up at its deadline: the summary, then one error line
    assert one["server_gone"] is True and "no reply" in one["gave_up"]
    assert 0 < one["acknowledged"] < 600

    server, url = _serve(study_folder, db_url, log)
    try:
        two = _summary(_simulate(study_folder, url, 10, 2, tmp_path / "r2.jsonl"))
    finally:
        server.terminate()
        server.wait(HANG_SECONDS)
    assert two["server_gone"] is False and two["completed"] == 10
    acknowledged = _receipts(tmp_path / "r1.jsonl") + _receipts(tmp_path / "r2.jsonl")
    assert len(acknowledged) == one["acknowledged"] + two["acknowledged"]

    out = tmp_path / "responses.csv"
    cmd = [*EMOTIVE, "study", "export", str(study_folder), "--out", str(out)]
    cmd += ["--db", db_url] if db_url else []
    subprocess.run(cmd, check=True, capture_output=True, timeout=HANG_SECONDS)
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    exported = Counter((r["participant"], int(r["item"]), r["question"]) for r in rows)
    assert max(exported.values()) == 1, "a value stored twice"
    missing = [k for k in acknowledged if k not in exported]
    assert not missing, f"acknowledged but lost: {missing[:5]}"
    # In flight at the kill: at most one submission per participant, 5 values each.
    assert len(rows) - len(acknowledged) <= 30 * 5

    report = tmp_path / "report"
    cmd = [*EMOTIVE, "study", "analyze", str(study_folder), "--out", str(report)]
    cmd += ["--db", db_url] if db_url else []
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=HANG_SECONDS)
    assert done.returncode == 0, done.stderr[-3000:]
    text = (report / "report.md").read_text()
    assert "Anderson-Darling" in text
    checked = {r["participant"] for r in rows if r["check"]}
    careless = set(one["careless"] + two["careless"]) & checked
    assert careless, "no careless rater reached the attention check"
    for participant in careless:
        assert participant in text, f"careless rater {participant} not flagged"
    assert os.path.getsize(report / "report.md") > 0
