"""One command's outputs are all or none: a command that fails on its second output (the
encoder failing, a full disk, a rename refused, Ctrl-C) leaves every file that was there before
byte for byte, adds none and leaves no temporary file (:func:`emotive.io.atomic.
output_transaction`). Every command with two or more outputs is run here, on synthetic
clips (no data needed)."""

from __future__ import annotations

import errno
import json
import os
import sys
from pathlib import Path

import pytest

import emotive.io.atomic as atomic
from disk_faults import fill_disk
from emotive.cli import main
from emotive.io.bvh import write_bvh

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "models" / "mar"))
from mar_helpers import styled

#: A stand-in for ffmpeg that fails at once (exit status 1), before reading a frame.
FAILING_ENCODER = "import sys; sys.stderr.write('Conversion failed!\\n'); sys.exit(1)"


def run(capsys, *args: object) -> tuple[int, str, str]:
    """Run ``emotive ARGS`` in-process; the exit code, stdout and stderr."""
    with pytest.raises(SystemExit) as exc:
        main([str(a) for a in args])
    out = capsys.readouterr()
    return exc.value.code, out.out, out.err


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file in ``folder`` (temporary ones included) with its bytes."""
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def old_files(folder: Path, *names: str) -> dict[str, bytes]:
    """Files of ``names`` in ``folder`` holding old bytes of their own; the snapshot."""
    folder.mkdir(exist_ok=True)
    for name in names:
        (folder / name).write_bytes(f"old {name}\n".encode())
    return snapshot(folder)


def failing_encoder(monkeypatch) -> None:
    """Make every video encoding fail as a failing ffmpeg does (exit status 1)."""
    from emotive.render import video

    monkeypatch.setattr(video, "_command", lambda *a: [sys.executable, "-c", FAILING_ENCODER])


def failing_rename(monkeypatch, dest: Path, exc: BaseException) -> list[Path]:
    """Make renaming a file onto ``dest`` raise ``exc``; the list of renames done before it."""
    real = os.replace
    done: list[Path] = []

    def replace(src, dst, **kwargs):
        if Path(dst) == dest:
            raise exc
        real(src, dst, **kwargs)
        done.append(Path(dst))

    monkeypatch.setattr(atomic.os, "replace", replace)
    return done


def assert_failed(code: int, out: str, err: str, *words: str) -> None:
    """Exit code 2, one ``error:`` line, the last, holding ``words``; no blank line, no
    "wrote"."""
    assert code == 2, (code, out, err)
    lines = err.splitlines()
    assert lines[-1].startswith("error: ") and err.count("error: ") == 1, err
    assert "" not in lines, err
    assert "wrote" not in out + err and all(w in lines[-1] for w in words), err


@pytest.fixture(scope="module")
def clips(tmp_path_factory) -> Path:
    """A folder of two synthetic walks with their intended emotions, for ``evaluate``."""
    folder = tmp_path_factory.mktemp("clips")
    write_bvh(styled("walk", "neutral", take=2), folder / "a.bvh", unit="cm")
    write_bvh(styled("walk", "sad", take=1), folder / "b.bvh", unit="cm")
    (folder / "labels.json").write_text(json.dumps({"a.bvh": {"emotion": "neutral"},
                                                    "b.bvh": {"emotion": "sad"}}))
    return folder


GENERATE = ("generate", "--seconds", "1")


def test_generate_whose_preview_fails_leaves_the_old_files(tmp_path, monkeypatch, capsys):
    before = old_files(tmp_path, "w.bvh", "w.npz", "w.mp4")
    failing_encoder(monkeypatch)
    result = run(capsys, *GENERATE, "-o", tmp_path / "w.bvh", "--npz", tmp_path / "w.npz",
                 "--preview", tmp_path / "w.mp4", "--force")
    assert_failed(*result, "w.mp4", "ffmpeg", "Conversion failed!")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(("fault", "code"), [(OSError(errno.EIO, "Input/output error"), 2),
                                             (KeyboardInterrupt(), 130)])
def test_generate_whose_second_rename_fails_puts_the_first_file_back(tmp_path, monkeypatch,
                                                                     capsys, fault, code):
    before = old_files(tmp_path, "w.bvh", "w.npz", "w.gif")
    done = failing_rename(monkeypatch, tmp_path / "w.npz", fault)
    result = run(capsys, *GENERATE, "-o", tmp_path / "w.bvh", "--npz", tmp_path / "w.npz",
                 "--preview", tmp_path / "w.gif", "--force")
    assert tmp_path / "w.bvh" in done  # the first file was in place, and is put back
    if code == 2:
        assert_failed(*result, "cannot write", "w.npz", "input/output error")
    else:
        assert result[0] == 130 and "wrote" not in result[2], result
    assert snapshot(tmp_path) == before


def test_generate_that_succeeds_replaces_every_old_file(tmp_path, capsys):
    before = old_files(tmp_path, "w.bvh", "w.npz")
    code, _, err = run(capsys, *GENERATE, "-o", tmp_path / "w.bvh", "--npz", tmp_path / "w.npz",
                       "--force")
    assert code in (0, None), err
    after = snapshot(tmp_path)
    assert sorted(after) == ["w.bvh", "w.npz"]
    assert all(after[name] != before[name] for name in after)
    assert after["w.bvh"].startswith(b"HIERARCHY") and after["w.npz"].startswith(b"PK")


def test_the_same_file_named_twice_is_refused_before_any_work(tmp_path, capsys):
    result = run(capsys, *GENERATE, "-o", tmp_path / "w.npz", "--npz", tmp_path / "w.npz")
    assert_failed(*result, "--npz", "the same file as --out", "its own file")
    assert list(tmp_path.iterdir()) == []


def test_deprecated_fcrbm_generate_whose_preview_fails_leaves_the_old_files(tmp_path,
                                                                             monkeypatch,
                                                                             capsys):
    before = old_files(tmp_path, "f.bvh", "f.gif")
    failing_encoder(monkeypatch)
    result = run(capsys, "fcrbm", "generate", "--emotion", "sad", "--seconds", "1", "-o",
                 tmp_path / "f.bvh", "--preview", tmp_path / "f.gif", "--force")
    assert_failed(*result, "f.gif", "ffmpeg")  # after the deprecation line
    assert snapshot(tmp_path) == before


def test_transfer_whose_preview_fails_leaves_the_old_files(tmp_path, monkeypatch, capsys,
                                                           index, clip):
    before = old_files(tmp_path, "p.bvh", "p.gif")
    failing_encoder(monkeypatch)
    result = run(capsys, "transfer", clip, "--style", "proud", "--index", index, "-o",
                 tmp_path / "p.bvh", "--preview", tmp_path / "p.gif", "--force")
    assert_failed(*result, "p.gif", "ffmpeg")
    assert snapshot(tmp_path) == before


def test_reconstruct_whose_preview_fails_leaves_the_old_files(tmp_path, monkeypatch, capsys,
                                                              clip):
    before = old_files(tmp_path, "r.bvh", "r.mp4")
    failing_encoder(monkeypatch)
    result = run(capsys, "reconstruct", clip, "-o", tmp_path / "r.bvh", "--preview",
                 tmp_path / "r.mp4", "--force")
    assert_failed(*result, "r.mp4", "ffmpeg")
    assert snapshot(tmp_path) == before


def test_features_whose_plot_meets_a_full_disk_leaves_the_old_files(tmp_path, monkeypatch,
                                                                    capsys, clip):
    import emotive.render.plots as plots

    before = old_files(tmp_path, "f.csv", "f.png")
    real = plots.atomic_output

    def plot_on_a_full_disk(path, *args, **kwargs):
        fill_disk(monkeypatch)
        return real(path, *args, **kwargs)

    monkeypatch.setattr(plots, "atomic_output", plot_on_a_full_disk)
    result = run(capsys, "features", clip, "-o", tmp_path / "f.csv", "--plot",
                 tmp_path / "f.png", "--force")
    assert_failed(*result, "f.png", "disk is full")
    assert snapshot(tmp_path) == before


def test_evaluate_whose_second_file_fails_to_move_in_leaves_the_old_report(tmp_path,
                                                                           monkeypatch,
                                                                           capsys, clips):
    report = tmp_path / "report"
    # The files of an older report, and one of the user's that the report does not make.
    before = old_files(report, "confusion.png", "intended_vs_perceived.png", "metrics.json",
                       "report.md", "notes.txt")
    done = failing_rename(monkeypatch, report / "intended_vs_perceived.png",
                          OSError(errno.EACCES, "Permission denied"))
    result = run(capsys, "evaluate", "--model", clips, "--suite", "emotion", "--out", report,
                 "--force")
    assert report / "confusion.png" in done
    assert_failed(*result, "intended_vs_perceived.png", "permission denied")
    assert snapshot(report) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report"]
