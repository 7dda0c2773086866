"""Tests of ``emotive generate`` and of the committed pretrained gait model (no data needed)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from emotive.core import Motion, Skeleton
from emotive.core.roles import resolve_roles
from emotive.eval import feet
from emotive.io.bvh import read_bvh, write_bvh
from emotive.models.gait.model import default_checkpoint_path, load_gait_model
from emotive.models.gait.walks import generate_walks
from emotive.paths import circle


def run(*args: str, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", "from emotive.cli import main; main()", *args],
                          capture_output=True, text=True, cwd=cwd)


def test_the_pretrained_checkpoint_is_small_and_loads():
    path = default_checkpoint_path()
    assert path.stat().st_size <= 25 * 2**20
    model = load_gait_model()
    assert {"happy", "sad", "angry", "neutral"} <= set(model.labels)
    assert (path.parent / "MODEL_CARD.md").exists()


def test_pretrained_walks_follow_the_path_with_paces_ordered_as_in_the_data():
    model = load_gait_model()
    emotions = ("sad", "neutral", "happy", "angry")
    walks = generate_walks(model, [circle()] * 4, list(emotions), 8.0)
    speeds = []
    for walk in walks:
        world = walk.motion.positions_with_end_sites()
        assert np.isfinite(world).all()
        hips = world[:, model.controls.mover]
        _, distance = circle().nearest(hips[:, [0, 2]])
        # On the path up to the float32 step and the 1 cm grid the host samples it from.
        assert distance.max() < 2e-5
        # Feet stay near the ground and the head above the hips (no collapse).
        assert world[:, :, 1].min() > -0.15
        head = model.controls.skeleton.index("Head")
        assert (world[:, head, 1] > hips[:, 1] + 0.3).all()
        speeds.append(np.linalg.norm(np.diff(hips[30:, [0, 2]], axis=0), axis=1).mean() * 30)
    # The stream's foot lock keeps planted feet still; the raw network lets them slide.
    raw = generate_walks(model, [circle()], ["happy"], 8.0, foot_lock=False)[0].motion
    roles = resolve_roles(raw.skeleton)
    skate = [float(feet.foot_skating(m.positions_with_end_sites(), roles, m.fps).mean_speed)
             for m in (raw, walks[2].motion)]
    assert skate[1] < 0.5 * skate[0]
    # The data's walking paces: sad slowest, angry fastest.
    assert speeds[0] < speeds[1] < speeds[3] and speeds[0] < speeds[2] < speeds[3]
    assert 0.2 < speeds[0] and speeds[3] < 3.5


def test_generate_writes_bvh_npz_and_preview_at_30_fps(tmp_path):
    out = run("generate", "--emotion", "happy=0.7,neutral=0.3", "--path", "circle",
              "--seconds", "3", "--out", str(tmp_path / "w.bvh"), "--npz",
              str(tmp_path / "w.npz"), "--preview", str(tmp_path / "w.gif"), "--seed", "2")
    assert out.returncode == 0, out.stderr
    motion = read_bvh(tmp_path / "w.bvh")
    assert motion.fps == 30.0 and motion.num_frames == 91
    _, distance = circle().nearest(motion.positions_with_end_sites()[:, 1][:, [0, 2]])
    assert distance.max() < 1e-3
    data = np.load(tmp_path / "w.npz")
    np.testing.assert_allclose(data["emotion"][:, list(data["labels"]).index("happy")], 0.7,
                               atol=1e-6)
    assert (tmp_path / "w.gif").stat().st_size > 0
    assert "wrote" in out.stderr


def test_generate_an_emotion_schedule_along_waypoints(tmp_path):
    schedule = tmp_path / "s.json"
    schedule.write_text(json.dumps([{"t": 0, "emotion": {"angry": 1}},
                                    {"t": 2, "emotion": {"happy": 1}}]))
    path = tmp_path / "p.json"
    path.write_text(json.dumps([[0, 0], [0, 2], [1, 4], [3, 4]]))
    out = run("generate", "--emotion-schedule", str(schedule), "--path", str(path),
              "--seconds", "3", "--out", str(tmp_path / "w.npz"))
    assert out.returncode == 0, out.stderr
    data = np.load(tmp_path / "w.npz")
    labels = list(data["labels"])
    assert data["emotion"][0, labels.index("angry")] == 1.0
    assert data["emotion"][-1, labels.index("happy")] == 1.0


def _other_rig_clip(path):
    """A clip of a three-joint chain: no humanoid, so no primer for any humanoid model."""
    sk = Skeleton(("A", "B", "C"), np.array([-1, 0, 1]),
                  np.array([[0.0, 0.9, 0.0], [0.0, 0.4, 0.0], [0.0, 0.4, 0.0]]),
                  end_site_parents=[2], end_site_offsets=[[0.0, 0.1, 0.0]])
    rot = np.zeros((10, 3, 4))
    rot[..., 0] = 1
    write_bvh(Motion(sk, rot, np.broadcast_to(sk.offsets, (10, 3, 3)).copy(), 30.0), path)


@pytest.mark.parametrize("args, message", [
    (["--emotion", "furious"], "unknown"),
    (["--emotion", "happy=-1"], "happy"),
    (["--emotion", "happy=0"], "zero"),
    (["--emotion", "happy", "--emotion-schedule", "x.json"], "not both"),
    (["--path", "spiral"], "unknown path"),
    (["--path", "one.json"], "two distinct"),
    (["--primer", "other.bvh"], "another rig"),
    (["--checkpoint", "bad.pt"], "not a gait checkpoint"),
    (["--preview", "w.avi"], "ending in"),
    (["--out", "w.txt"], "ending in"),
    (["--out", "missing/w.bvh"], "does not exist"),
])
def test_bad_input_is_a_one_line_error_and_writes_nothing(tmp_path, args, message):
    (tmp_path / "one.json").write_text("[[1, 1], [1, 1]]")
    (tmp_path / "bad.pt").write_bytes(b"garbage")
    _other_rig_clip(tmp_path / "other.bvh")
    before = set(tmp_path.iterdir())
    base = ["generate", "--seconds", "1"]
    if "--out" not in args:
        base += ["--out", "w.bvh"]
    out = run(*base, *args, cwd=tmp_path)
    assert out.returncode == 2, out.stderr
    assert message in out.stderr and len(out.stderr.strip().splitlines()) == 1
    assert set(tmp_path.iterdir()) == before
