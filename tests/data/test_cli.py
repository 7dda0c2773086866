"""``emotive data list | fetch | path | stats``."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from emotive import cli
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
