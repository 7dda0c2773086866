"""``--unit`` on every command that reads BVH: one spelling, aliases, a one-line error."""

from __future__ import annotations

import pytest
from test_info_command import make_walk

from cli_helpers import run_main
from emotive.commands.options import length_unit, read_input
from emotive.io.bvh import write_bvh

READERS = [
    ["info", "clip.bvh"],
    ["features", "clip.bvh", "-o", "f.csv"],
    ["classify", "clip.bvh"],
    ["preview", "clip.bvh", "-o", "v.gif"],
    ["reconstruct", "clip.bvh", "-o", "r.bvh"],
    ["transfer", "clip.bvh", "--style", "happy", "-o", "t.bvh"],
    ["generate", "--primer", "clip.bvh", "-o", "g.bvh"],
]


@pytest.mark.parametrize("args", READERS, ids=lambda a: a[0])
def test_an_unknown_unit_is_one_error_line_before_any_work(monkeypatch, capsys, tmp_path,
                                                           args):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_main(monkeypatch, capsys, *args, "--unit", "furlong")
    assert code == 2 and out == ""
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert "'furlong' is not a length unit" in err and "cm" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("given", "shown", "scale"), [
    ("auto", "m", 1.0), ("m", "m", 1.0), ("cm", "cm", 0.01), ("inch", "in", 0.0254),
    ("MM", "mm", 0.001),
])
def test_the_file_is_read_in_the_unit_given(monkeypatch, capsys, tmp_path, given, shown,
                                            scale):
    walk = make_walk()
    write_bvh(walk, tmp_path / "clip.bvh", unit="m")
    monkeypatch.chdir(tmp_path)
    code, out, _ = run_main(monkeypatch, capsys, "info", "clip.bvh", "--unit", given)
    assert code == 0
    assert f"file unit: {shown}" in out
    read = read_input(tmp_path / "clip.bvh", length_unit(given))
    assert read.skeleton.offsets == pytest.approx(walk.skeleton.offsets * scale, abs=1e-6)
