"""``emotive serve`` on the command line: refusals in one line, exit code 2, a light --help."""

from __future__ import annotations

import socket
import subprocess
import sys

from cli_helpers import run_main


def test_other_host_without_token_exits_2(monkeypatch, capsys):
    code, out, err = run_main(monkeypatch, capsys, "serve", "--host", "0.0.0.0")
    assert code == 2 and out == ""
    assert err.startswith("error: --host 0.0.0.0") and "--token" in err
    assert len(err.strip().splitlines()) == 1


def test_bad_options_exit_2(monkeypatch, capsys):
    code, _, err = run_main(monkeypatch, capsys, "serve", "--model", "lgb")
    assert code == 2 and "streaming model" in err
    code, _, err = run_main(monkeypatch, capsys, "serve", "--max-agents", "0")
    assert code == 2 and "max-agents" in err
    code, _, err = run_main(monkeypatch, capsys, "serve", "--max-agents-per-client", "0")
    assert code == 2 and "max-agents-per-client must be a positive number" in err
    code, _, err = run_main(monkeypatch, capsys, "serve", "--workers", "0")
    assert code == 2 and "--workers must be a whole number 1-64" in err
    code, _, err = run_main(monkeypatch, capsys, "serve", "--step-budget", "0")
    assert code == 2 and "--step-budget is a share of a frame" in err
    code, _, err = run_main(monkeypatch, capsys, "serve", "--worker-kind", "fibers")
    assert code == 2 and "--worker-kind 'fibers' is unknown" in err and "threads" in err


def test_a_port_in_use_is_named(monkeypatch, capsys):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        code, _, err = run_main(monkeypatch, capsys, "serve", "--port", str(port))
    assert code == 2 and f"127.0.0.1:{port}" in err and "--port" in err


def test_help_does_not_import_torch():
    code = ("import sys; from emotive.cli import main\n"
            "try:\n    main(['serve', '--help'])\nexcept SystemExit:\n    pass\n"
            "assert 'torch' not in sys.modules, 'torch imported'\n"
            "assert 'emotive.serve.app' not in sys.modules\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 0, result.stderr
    assert "--max-agents" in result.stdout and "--token" in result.stdout


def test_without_the_serve_extra_the_fix_is_named():
    code = ("import sys; sys.modules['fastapi'] = None\nfrom emotive.cli import main\n"
            "main(['serve'])\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 2
    assert "emotive[serve]" in result.stderr and "fastapi" in result.stderr
