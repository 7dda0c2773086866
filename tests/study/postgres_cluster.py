"""A throwaway PostgreSQL cluster in a temporary folder, for the study tests and benchmarks.

``.ci/run`` starts one before the suite and stops it after::

    python tests/study/postgres_cluster.py start DIR   # prints the server's URL
    python tests/study/postgres_cluster.py stop DIR

The tests read the URL from ``EMOTIVE_TEST_POSTGRES_URL``; without it, the ``postgres_url``
fixture starts a cluster of its own when Debian's ``postgresql`` package is installed.
The cluster listens on 127.0.0.1 at a free port with trust authentication for the
``postgres`` user; as root, its programs run as the ``postgres`` system user (initdb refuses
root).
"""

from __future__ import annotations

import glob
import os
import pwd
import shutil
import socket
import subprocess
import sys
from pathlib import Path

#: Seconds pg_ctl waits for the server to start or stop.
WAIT_SECONDS = 120


def bin_dir() -> Path | None:
    """The newest ``/usr/lib/postgresql/N/bin`` with ``pg_ctl``, or the one on PATH."""
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/pg_ctl"),
                   key=lambda p: int(Path(p).parts[-3]))
    if found:
        return Path(found[-1]).parent
    on_path = shutil.which("pg_ctl")
    return Path(on_path).parent if on_path else None


def _as_owner(cmd: list[str]) -> list[str]:
    if os.geteuid() != 0:
        return cmd
    return ["runuser", "-u", "postgres", "--", *cmd]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def start(folder: Path) -> str:
    """Create and start a cluster in ``folder``; return the URL of its ``postgres`` database."""
    binaries = bin_dir()
    if binaries is None:
        raise RuntimeError("PostgreSQL is not installed (apt-get install postgresql)")
    folder.mkdir(parents=True, exist_ok=True)
    data = folder / "data"
    if os.geteuid() == 0:
        owner = pwd.getpwnam("postgres")
        os.chown(folder, owner.pw_uid, owner.pw_gid)
    subprocess.run(_as_owner([str(binaries / "initdb"), "-D", str(data), "-U", "postgres",
                              "--auth=trust", "--no-sync", "-E", "UTF8"]),
                   check=True, capture_output=True, text=True)
    port = _free_port()
    options = (f"-p {port} -k {folder} -c listen_addresses=127.0.0.1 -c fsync=on "
               "-c max_connections=200")
    subprocess.run(_as_owner([str(binaries / "pg_ctl"), "-D", str(data), "-l",
                              str(folder / "server.log"), "-o", options, "-w", "-t",
                              str(WAIT_SECONDS), "start"]),
                   check=True, capture_output=True, text=True)
    (folder / "port").write_text(str(port))
    return f"postgresql://postgres@127.0.0.1:{port}/postgres"


def stop(folder: Path) -> None:
    """Stop the cluster in ``folder`` (fast shutdown) and remove the folder."""
    binaries = bin_dir()
    if binaries is not None and (folder / "data").is_dir():
        subprocess.run(_as_owner([str(binaries / "pg_ctl"), "-D", str(folder / "data"), "-m",
                                  "fast", "-w", "-t", str(WAIT_SECONDS), "stop"]),
                       check=False, capture_output=True, text=True)
    shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    verb, where = sys.argv[1], Path(sys.argv[2])
    if verb == "start":
        print(start(where))
    else:
        stop(where)
