"""Output faults through the command line: a full disk, a read-only folder, a folder named as
the output, absurd weights and lengths. Each is one ``error:`` line, exit code 2, no output left
and no "wrote" line (the faults are simulated: :mod:`disk_faults`)."""

from __future__ import annotations

import errno
from pathlib import Path

import pytest

from disk_faults import fill_disk, refuse_files
from emotive.cli import main


def run(capsys, *args: object) -> tuple[int, str, str]:
    """Run ``emotive ARGS`` in-process; the exit code, stdout and stderr."""
    with pytest.raises(SystemExit) as exc:
        main([str(a) for a in args])
    out = capsys.readouterr()
    return exc.value.code, out.out, out.err


def assert_one_error(code: int, out: str, err: str, *words: str) -> None:
    """Exit code 2, nothing on stdout, one ``error:`` line holding ``words``, no "wrote"."""
    assert code == 2 and out == "", (code, out, err)
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert "wrote" not in err and all(w in err for w in words), err


def test_generate_onto_a_full_disk_leaves_no_bvh_and_no_gif(tmp_path, monkeypatch, capsys):
    fill_disk(monkeypatch)
    result = run(capsys, "generate", "--seconds", "1", "-o", tmp_path / "w.bvh", "--preview",
                 tmp_path / "w.gif")
    assert_one_error(*result, "cannot write", "w.bvh", "disk is full", "free space")
    assert list(tmp_path.iterdir()) == []


def test_a_full_disk_while_encoding_the_gif_removes_the_bvh_too(tmp_path, monkeypatch, capsys):
    import emotive.render.preview as preview

    real = preview.atomic_output

    def gif_on_full_disk(path, *args, **kwargs):
        fill_disk(monkeypatch)
        return real(path, *args, **kwargs)

    monkeypatch.setattr(preview, "atomic_output", gif_on_full_disk)
    result = run(capsys, "generate", "--seconds", "1", "-o", tmp_path / "w.bvh", "--preview",
                 tmp_path / "w.gif")
    assert_one_error(*result, "cannot write", "w.gif", "disk is full")
    assert list(tmp_path.iterdir()) == []


def test_transfer_onto_a_full_disk(tmp_path, monkeypatch, capsys, index, clip):
    fill_disk(monkeypatch)
    result = run(capsys, "transfer", clip, "--style", "proud", "--index", index, "-o",
                 tmp_path / "p.bvh")
    assert_one_error(*result, "p.bvh", "disk is full")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("code", "words"), [
    (errno.EROFS, ["--out", "read-only", "choose another folder"]),
    (errno.EACCES, ["--out", "permission denied"]),
    (errno.EPERM, ["--out", "may not be changed"]),
])
def test_a_folder_that_refuses_files_is_refused_before_any_work(tmp_path, monkeypatch, capsys,
                                                                 code, words):
    refuse_files(monkeypatch, code)
    result = run(capsys, "generate", "--seconds", "1", "-o", tmp_path / "w.bvh")
    assert_one_error(*result, str(tmp_path), *words)
    assert list(tmp_path.iterdir()) == []


def _folder_cases(clip: Path, index: Path, folder: Path) -> list[list[object]]:
    return [
        ["generate", "--seconds", "1", "-o", folder],
        ["generate", "--seconds", "1", "-o", folder / "a.bvh", "--preview", folder],
        ["transfer", clip, "--style", "proud", "--index", index, "-o", folder],
        ["reconstruct", clip, "-o", folder],
        ["preview", clip, "-o", folder],
        ["features", clip, "-o", folder],
    ]


@pytest.mark.parametrize("case", range(6))
def test_a_folder_named_as_the_output_is_one_error(tmp_path, capsys, clip, index, case):
    folder = tmp_path / "taken.gif"
    folder.mkdir()
    args = _folder_cases(clip, index, folder)[case]
    assert_one_error(*run(capsys, *args), str(folder), "that is a folder", "name a file")
    assert [p.name for p in tmp_path.iterdir()] == ["taken.gif"]
    assert list(folder.iterdir()) == []


def _file_parent_cases(clip: Path, index: Path, notes: Path) -> list[list[object]]:
    return [
        ["generate", "--seconds", "1", "-o", notes / "a.bvh"],
        ["generate", "--seconds", "1", "-o", notes.parent / "a.bvh", "--preview",
         notes / "deeper" / "a.gif"],
        ["transfer", clip, "--style", "proud", "--index", index, "-o", notes / "a.bvh"],
        ["reconstruct", clip, "-o", notes / "a.bvh"],
        ["preview", clip, "-o", notes / "a.mp4"],
        ["features", clip, "-o", notes / "a.csv"],
    ]


@pytest.mark.parametrize("case", range(6))
def test_an_output_inside_a_file_says_the_file_is_no_folder(tmp_path, capsys, clip, index,
                                                            case):
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    args = _file_parent_cases(clip, index, notes)[case]
    assert_one_error(*run(capsys, *args), f"{notes} is a file, not a folder",
                     "put the file in a folder")
    assert [p.name for p in tmp_path.iterdir()] == ["notes.txt"]
    assert notes.read_text() == "mine"


def test_a_file_named_as_the_report_folder_is_one_error(tmp_path, capsys):
    taken = tmp_path / "report"
    taken.write_text("mine")
    result = run(capsys, "evaluate", "--model", tmp_path, "--out", taken / "sub")
    assert_one_error(*result, "--out", "is a file, not a folder")
    assert taken.read_text() == "mine"


def test_proportional_weights_give_the_same_walk_as_normalized_ones(tmp_path, capsys):
    half, plain = tmp_path / "half.bvh", tmp_path / "plain.bvh"
    for out, emotion in ((half, "happy=0.5,sad=0.5"), (plain, "happy=1,sad=1")):
        code, _, err = run(capsys, "generate", "--seconds", "1", "-e", emotion, "-o", out)
        assert code == 0, err
    assert half.read_bytes() == plain.read_bytes()


def test_proportional_weights_give_the_same_transfer_as_normalized_ones(tmp_path, capsys, index,
                                                                        clip):
    half, plain = tmp_path / "half.bvh", tmp_path / "plain.bvh"
    lines = []
    for out, style in ((half, "proud=0.5,sad=0.5"), (plain, "proud=1,sad=1")):
        code, stdout, err = run(capsys, "transfer", clip, "--style", style, "--index", index,
                                "-o", out)
        assert code == 0, err
        lines.append(stdout)
    assert half.read_bytes() == plain.read_bytes()
    assert "in style proud=0.5,sad=0.5;" in lines[1]


@pytest.mark.parametrize("weights", ["happy=1e309,sad=1", "happy=inf", "happy=nan",
                                     "happy=0,sad=0", "happy=-1e308,sad=1e308",
                                     "happy=1e308,sad=1e308", "happy=2"])
def test_weights_not_finite_or_summing_to_zero_are_one_error_everywhere(tmp_path, capsys,
                                                                        index, clip, weights):
    result = run(capsys, "generate", "--seconds", "1", "-e", weights, "-o", tmp_path / "w.bvh")
    assert_one_error(*result)
    style = weights.replace("happy", "proud").replace("sad", "neutral")
    result = run(capsys, "transfer", clip, "--style", style, "--index", index, "-o",
                 tmp_path / "t.bvh")
    assert_one_error(*result, "--style")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("model", ["gait", "fcrbm"])
@pytest.mark.parametrize("seconds", ["1e6", "inf", "-inf", "1e308"])
def test_lengths_beyond_the_limit_are_one_error(tmp_path, capsys, model, seconds):
    result = run(capsys, "generate", "--model", model, "--seconds", seconds, "-o",
                 tmp_path / "w.bvh")
    assert_one_error(*result, "--seconds")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.data
@pytest.mark.parametrize("seconds", ["1e6", "inf"])
def test_lengths_beyond_the_limit_are_one_error_for_lgb(tmp_path, capsys, bandai1_dir,
                                                        seconds):
    result = run(capsys, "generate", "--model", "lgb", "--seconds", seconds, "-o",
                 tmp_path / "w.bvh")
    assert_one_error(*result, "--seconds")
    assert list(tmp_path.iterdir()) == []
