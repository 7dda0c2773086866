"""Tests of the feature plots."""

from __future__ import annotations

import errno

import numpy as np
import pytest

from emotive.errors import OutputError
from emotive.features.affective import AFFECTIVE_FEATURE_KINDS, AFFECTIVE_FEATURE_NAMES
from emotive.features.movement import MOVEMENT_FEATURE_NAMES
from emotive.render.plots import _runs, plot_features


def test_runs():
    assert _runs(np.array([1, 1, 0, 1, 0, 0, 1], dtype=bool)) == [(0, 2), (3, 4), (6, 7)]
    assert _runs(np.zeros(3, dtype=bool)) == []


@pytest.mark.parametrize(("suffix", "magic"), [(".png", b"\x89PNG"), (".svg", b"<?xml"),
                                               (".pdf", b"%PDF")])
def test_plot_writes_one_image(tmp_path, rng, suffix, magic):
    n = 40
    contacts = np.zeros((n, 2), dtype=bool)
    contacts[5:20, 0] = contacts[18:35, 1] = True
    out = plot_features(
        tmp_path / f"features{suffix}", np.arange(n) / 30.0, rng.normal(size=(n, 18)),
        AFFECTIVE_FEATURE_NAMES, AFFECTIVE_FEATURE_KINDS,
        rng.normal(size=(n, len(MOVEMENT_FEATURE_NAMES))), MOVEMENT_FEATURE_NAMES, contacts,
        title="synthetic",
    )
    assert out.read_bytes().startswith(magic)
    assert [p.name for p in tmp_path.iterdir()] == [f"features{suffix}"]


def _plot(path, affective_columns: int = 18):
    return plot_features(
        path, np.arange(3.0), np.zeros((3, affective_columns)),
        AFFECTIVE_FEATURE_NAMES, AFFECTIVE_FEATURE_KINDS, np.zeros((3, 7)),
        MOVEMENT_FEATURE_NAMES, np.zeros((3, 2), dtype=bool),
    )


def test_shapes_checked(tmp_path):
    with pytest.raises(ValueError, match="shapes"):
        _plot(tmp_path / "features.png", affective_columns=17)
    assert list(tmp_path.iterdir()) == []


def test_failed_save_leaves_nothing(tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    def broken(self, fname, **kwargs):
        with open(fname, "wb") as fh:
            fh.write(b"half an image")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Figure, "savefig", broken)
    (tmp_path / "features.png").write_bytes(b"old")
    with pytest.raises(OutputError, match=r"features\.png.*disk is full"):
        _plot(tmp_path / "features.png")
    assert [p.name for p in tmp_path.iterdir()] == ["features.png"]
    assert (tmp_path / "features.png").read_bytes() == b"old"
