"""``emotive data list | fetch | path | stats``."""

from __future__ import annotations

import errno
import os
import shutil
import sys
import tarfile
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from emotive import cli
from emotive.commands import data as data_command
from emotive.data import registry, store
from emotive.data.stats import frame_stats
from emotive.errors import DataError

runner = CliRunner()


def invoke(*args: str):
    result = runner.invoke(cli.app, ["data", *args], env={"COLUMNS": "200"})
    if result.exception and not isinstance(result.exception, SystemExit):
        raise result.exception
    return result


def test_list_states(fake, no_shared_data, monkeypatch):
    out = invoke("list").output
    for name in ("bandai-namco-1", "bandai-namco-2-locomotion", "fake-1"):
        assert name in out
    assert "missing" in out and "emotive data fetch fake-1" in out
    monkeypatch.setenv("EMOTIVE_DATA", str(fake.archive.parent))
    assert "available in shared data" in invoke("list").output
    invoke("fetch", "fake-1")
    assert "cached" in invoke("list").output


def test_fetch_prints_attribution(fake, isolated_home):
    result = invoke("fetch", "fake-1", "--source", str(fake.archive))
    assert result.exit_code == 0, result.output
    assert "CC BY-NC 4.0" in result.output and "non-commercial" in result.output
    assert "BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset" in result.output
    assert f"ready in {isolated_home / 'datasets' / fake.info.folder}" in result.output
    again = invoke("fetch", "fake-1")
    assert "already in the cache" in again.output


def test_path_unpacks_shared_archive_and_prints_folder(fake, isolated_home, no_shared_data,
                                                      monkeypatch):
    with pytest.raises(DataError, match="emotive data fetch fake-1"):
        invoke("path", "fake-1")
    monkeypatch.setenv("EMOTIVE_DATA", str(fake.archive.parent))
    result = invoke("path", "fake-1")
    folder = isolated_home / "datasets" / fake.info.folder
    assert result.exit_code == 0 and result.output.strip() == str(folder)
    assert sorted(p.stem for p in (folder / "data").glob("*.bvh")) == sorted(fake.frames)


def test_fetch_over_http(fake, http):
    http.routes["/a.tar.gz"] = (fake.archive.read_bytes(), "range")
    result = invoke("fetch", "fake-1", "--source", http.url("/a.tar.gz"))
    assert result.exit_code == 0, result.output


def test_errors_are_one_line_and_exit_2(fake, tmp_path, monkeypatch, capsys):
    bad = tmp_path / "bad.tar.gz"
    bad.write_bytes(b"broken")
    for argv, message in (
        (["data", "fetch", "bandai-namco1"], "did you mean 'bandai-namco-1'"),
        (["data", "fetch", "fake-1", "--source", str(bad)], "corrupt"),
    ):
        monkeypatch.setattr(sys, "argv", ["emotive", *argv])
        with pytest.raises(SystemExit) as exit_info:
            cli.main()
        assert exit_info.value.code == 2
        err = capsys.readouterr().err
        assert err.startswith("error: ") and message in err and err.count("\n") == 1


def test_stats_table(fake):
    invoke("fetch", "fake-1", "--source", str(fake.archive))
    stats = frame_stats("fake-1")
    assert stats.frames["all"].sum() == sum(fake.frames.values())
    for split in ("train", "val", "test"):
        assert (stats.clips[split].sum(axis=0) > 0).all()
    np.testing.assert_array_equal(
        stats.frames["train"] + stats.frames["val"] + stats.frames["test"], stats.frames["all"]
    )
    out = invoke("stats", "fake-1").output
    assert "walk-left" in out and str(sum(fake.frames.values())) in out
    md = invoke("stats", "fake-1", "--markdown").output.splitlines()
    total = [line for line in md if line.startswith("| all | all |")]
    assert total == [
        f"| all | all | {stats.frames['train'].sum()} | {stats.frames['val'].sum()} | "
        f"{stats.frames['test'].sum()} | {stats.frames['all'].sum()} | 12/3/3 |"
    ]
    loco = frame_stats("fake-1", locomotion=True)
    assert loco.contents == ("walk", "walk-left")


def test_stats_real_dataset1(home):
    md = invoke("stats", "bandai-namco-1", "--markdown").output
    assert "| all | all |" in md and "| 31914 | " in md


def run_main(monkeypatch, capsys, *args: str) -> tuple[int, str, str]:
    monkeypatch.setattr(sys, "argv", ["emotive", "data", *args])
    with pytest.raises(SystemExit) as exit_info:
        cli.main()
    out = capsys.readouterr()
    return exit_info.value.code, out.out, out.err


def leftovers(home: Path) -> list[str]:
    """Everything under the cache but its (empty) folders."""
    return sorted(str(p.relative_to(home)) for p in home.rglob("*") if not p.is_dir())


def full_disk(monkeypatch) -> None:
    """Every copy into the cache (archive copy, member unpack) fails after a first write."""

    def copy_then_fail(src, dst, length=0):
        dst.write(src.read(1024))
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(shutil, "copyfileobj", copy_then_fail)


def read_only(monkeypatch, home: Path) -> None:
    """Creating anything under ``home`` fails as on a read-only file system (root ignores
    permission bits, so chmod cannot make one)."""
    real_mkdir, real_open = os.mkdir, os.open

    def refuse(path) -> None:
        if Path(path).is_relative_to(home):
            raise OSError(errno.EROFS, "Read-only file system", str(path))

    def mkdir(path, *args, **kwargs):
        refuse(path)
        return real_mkdir(path, *args, **kwargs)

    def open_(path, flags, *args, **kwargs):
        if flags & (os.O_CREAT | os.O_WRONLY | os.O_RDWR):
            refuse(path)
        return real_open(path, flags, *args, **kwargs)

    monkeypatch.setattr(os, "mkdir", mkdir)
    monkeypatch.setattr(os, "open", open_)


@pytest.mark.parametrize("command", ["fetch", "path"])
@pytest.mark.parametrize("fault", ["full-disk", "read-only-new", "read-only-existing"])
def test_disk_faults_are_one_line_and_leave_nothing(command, fault, fake, isolated_home,
                                                    no_shared_data, monkeypatch, capsys):
    monkeypatch.setenv("EMOTIVE_DATA", str(fake.archive.parent))
    if fault == "read-only-existing":
        (isolated_home / "datasets").mkdir(parents=True)
        (isolated_home / "archives").mkdir()
    if fault == "full-disk":
        full_disk(monkeypatch)
    else:
        read_only(monkeypatch, isolated_home)
    code, out, err = run_main(monkeypatch, capsys, command, "fake-1")
    assert code == 2, err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    if fault == "full-disk":
        assert "no space left on the disk holding" in err and "free some space" in err
    else:
        assert "read-only" in err and "set EMOTIVE_HOME to a writable folder" in err
    assert str(isolated_home) in err and "Traceback" not in out + err
    assert not isolated_home.exists() or leftovers(isolated_home) == []
    assert not store.is_cached("fake-1")


def test_fetch_refuses_links_in_archive(fake_tools, tmp_path, monkeypatch, capsys,
                                        isolated_home):
    folder, _ = fake_tools.write_folder(tmp_path / "unpacked")
    link = tarfile.TarInfo(f"{folder.name}/data/escape")
    link.type, link.linkname = tarfile.SYMTYPE, "../../../.."
    archive = tmp_path / "fake-motion-1.tar.gz"
    info = fake_tools.info(fake_tools.pack(folder, archive, [(link, None)]))
    monkeypatch.setitem(registry.REGISTRY, info.name, info)
    code, _, err = run_main(monkeypatch, capsys, "fetch", "fake-1", "--source", str(archive))
    assert code == 2 and err.count("\n") == 1
    assert f"'{folder.name}/data/escape' is a symbolic link" in err
    assert not (isolated_home / "datasets" / info.folder).exists()


def test_verify_reports_damage_in_one_table_and_fetch_repairs(fake, isolated_home, monkeypatch,
                                                               capsys):
    monkeypatch.setenv("COLUMNS", "200")
    invoke("fetch", "fake-1", "--source", str(fake.archive))
    code, out, err = run_main(monkeypatch, capsys, "verify", "fake-1")
    assert (code, err) == (0, "") and "all 39 files in" in out and "match its archive" in out
    folder = isolated_home / "datasets" / fake.info.folder
    clip = folder / "data" / "dataset-1_walk_sad_002.bvh"
    original = clip.read_bytes()
    clip.write_bytes(original[:-1] + bytes([original[-1] ^ 1]))
    (folder / "LICENSE").unlink()
    code, out, err = run_main(monkeypatch, capsys, "verify", "fake-1")
    assert code == 1 and err == ""
    assert "1 damaged, 1 missing, 0 extra of 39 files" in out
    rows = [line for line in out.splitlines() if "│" in line]
    assert [[c.strip() for c in row.split("│")[1:3]] for row in rows] == [
        ["missing", "LICENSE"], ["damaged", "data/dataset-1_walk_sad_002.bvh"]
    ]
    assert out.splitlines()[-1] == (
        "fix: run `emotive data fetch fake-1` to unpack the damaged and missing files again "
        "and remove the extra ones"
    )
    monkeypatch.setattr(data_command, "MAX_ROWS", 1)
    out = run_main(monkeypatch, capsys, "verify", "fake-1")[1]
    assert "LICENSE" in out and "walk_sad_002" not in out and "│ 1 more " in out
    code, out, err = run_main(monkeypatch, capsys, "fetch", "fake-1")
    assert code == 0, err
    assert "fake-1 repaired from its archive: 1 damaged, 1 missing, 0 extra (LICENSE, " in out
    assert clip.read_bytes() == original
    assert run_main(monkeypatch, capsys, "verify", "fake-1")[0] == 0


def test_verify_never_unpacked_is_one_line(fake, no_shared_data, monkeypatch, capsys):
    code, out, err = run_main(monkeypatch, capsys, "verify", "fake-1")
    assert code == 2 and out == "" and err.count("\n") == 1
    assert err.startswith("error: data set 'fake-1' is not unpacked in the cache")
    assert "run `emotive data fetch fake-1` first" in err


def test_read_only_cache_is_verified_and_used_but_not_repaired(fake, isolated_home,
                                                              monkeypatch, capsys):
    invoke("fetch", "fake-1", "--source", str(fake.archive))
    datasets = isolated_home / "datasets"
    leftover = datasets / f".{fake.info.folder}.k1ll3d_x"
    leftover.mkdir()
    with monkeypatch.context() as mp:
        read_only(mp, isolated_home)
        assert store.dataset_dir("fake-1") == datasets / fake.info.folder
        assert run_main(mp, capsys, "verify", "fake-1")[0] == 0
        code, out, _ = run_main(mp, capsys, "fetch", "fake-1")
        assert code == 0 and "all 39 files match its archive" in out
    (datasets / fake.info.folder / "LICENSE").unlink()
    with monkeypatch.context() as mp:
        read_only(mp, isolated_home)
        assert run_main(mp, capsys, "verify", "fake-1")[0] == 1
        code, _, err = run_main(mp, capsys, "fetch", "fake-1")
        assert code == 2 and err.count("\n") == 1
        assert "has 1 damaged, missing or extra files" in err and "read-only" in err
    assert leftover.exists()  # nothing could be removed while read-only
    assert run_main(monkeypatch, capsys, "fetch", "fake-1")[0] == 0
    assert not leftover.exists() and store.verify("fake-1").clean
