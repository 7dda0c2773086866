"""Building, saving and loading the index."""

from __future__ import annotations

import numpy as np
import pytest
from mar_helpers import CONFIG, STYLES, cycle_frames, examples

from emotive.models.mar.build import build_database
from emotive.models.mar.config import MARConfig, TransferError
from emotive.models.mar.database import MARDatabase


def test_the_index_holds_registered_annotated_frames(mar_db):
    db = mar_db
    assert db.groups == ("synthetic/walk", "synthetic/wave")
    assert db.styles == ("neutral", "proud", "sad") and db.num_classes == 6
    assert db.num_frames == 4 * sum(cycle_frames(s) for s in STYLES)
    assert db.features.shape == (db.num_frames, CONFIG.pca_dims)
    # Canonical time grows within every clip; the walk (a gait, registered by cycles) wraps
    # around its canonical cycle, whose track has one row more than the cycle (closing it).
    for a, b in zip(db.clip_start[:-1], db.clip_start[1:], strict=True):
        c = db.frame_class[a]
        rows = db.track_start[c + 1] - db.track_start[c]
        step = np.diff(db.tau[a:b])
        if db.class_action(c) == "walk":
            assert db.tau[a:b].max() < rows - 1 and (step < 0).sum() >= 2
            step = np.mod(step, rows - 1)
        assert np.all(step > 0)
    # A slower style takes more of its frames per canonical frame than the neutral reference.
    walk = db.classes_where("walk")
    rate = {db.class_style[c]: db.track_rate[db.track_start[c]:db.track_start[c + 1]].mean()
            for c in walk}
    assert rate["neutral"] == pytest.approx(1.0, abs=0.05)
    assert rate["sad"] == pytest.approx(1.0 / STYLES["sad"][0], rel=0.05)
    assert rate["proud"] == pytest.approx(1.0 / STYLES["proud"][0], rel=0.05)
    assert db.output_classes().shape == (6, 3) and (db.output_classes() >= 0).all()


def test_save_and_load_give_the_same_index(mar_db, tmp_path):
    path = mar_db.save(tmp_path / "index.npz")
    back = MARDatabase.load(path)
    assert back.config == mar_db.config and back.groups == mar_db.groups
    assert back.class_style == mar_db.class_style and back.skeleton.same_as(mar_db.skeleton)
    for name in ("vectors", "points", "features", "tau", "track_pose", "contacts", "rest"):
        np.testing.assert_array_equal(getattr(back, name), getattr(mar_db, name))
    assert not list(tmp_path.glob(".*tmp*"))


def test_bad_files_labels_and_configs_raise_typed_errors(mar_db, tmp_path):
    with pytest.raises(TransferError, match=r"does not exist.*--build-index"):
        MARDatabase.load(tmp_path / "missing.npz")
    broken = tmp_path / "broken.npz"
    broken.write_bytes(b"not an index")
    with pytest.raises(TransferError, match=r"cannot be read.*--force"):
        MARDatabase.load(broken)
    with pytest.raises(TransferError, match=r"unknown action 'jump'.*walk, wave"):
        mar_db.classes_where("jump")
    with pytest.raises(TransferError, match="unknown input style 'happy'"):
        mar_db.classes_where(None, "happy")
    with pytest.raises(TransferError, match="rho"):
        MARConfig(rho=1.5)
    one_style = [e for e in examples(1) if e.style == "neutral"]
    with pytest.raises(TransferError, match="at least two styles"):
        build_database(one_style, CONFIG)


def test_a_cycle_track_weighs_every_take_alike():
    """A fast and a slow take, three cycles each: the track's swing and duration are the
    plain means of the takes' (pooling their frames would weigh the slow take twice as
    much: a swing of 1.0 and 1.11 frames per canonical frame)."""
    from emotive.models.mar.build import _cycle_track
    from emotive.models.mar.registration import GaitCycle

    cycle = GaitCycle(30.0, 15.0)
    encoded, taus, rates = [], [], []
    for period, amplitude in ((20, 2.0), (40, 0.5)):
        t = np.arange(3 * period + 2)
        phase = (t - 1) * cycle.length / period  # left strikes at 1, 1 + period, ...
        vectors = amplitude * np.sin(2 * np.pi * phase / cycle.length)[:, None]
        contacts = np.zeros((len(t), 2), dtype=bool)
        for k in range(3):
            contacts[1 + k * period:1 + k * period + period // 4, 0] = True
            contacts[1 + k * period + period // 2:1 + k * period + 3 * period // 4, 1] = True
        encoded.append((vectors, None, contacts))
        taus.append(cycle.wrap(phase))
        rates.append(np.full(len(t), cycle.length / period))
    pose, per, _ = _cycle_track([0, 1], cycle, encoded, taus, rates)
    assert pose.shape == (31, 1)
    swing = np.sin(2 * np.pi * np.arange(30) / 30.0)
    assert pose[:30, 0] @ swing / (swing @ swing) == pytest.approx(1.25, abs=0.05)
    np.testing.assert_allclose(per, 1.0, atol=0.03)  # (20 + 40) / 2 frames per 30
