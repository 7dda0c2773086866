"""Stick-figure previews: frames, rates, what is drawn, atomic output and bad input."""

from __future__ import annotations

import signal
import sys

import imageio_ffmpeg
import numpy as np
import pytest

from disk_faults import fill_disk
from emotive.cli import main
from emotive.errors import OutputError
from emotive.io.bvh import write_bvh
from emotive.paths import figure8
from emotive.render import video as video_mod
from emotive.render.preview import PreviewError, bones, render_preview
from emotive.render.video import VideoEncoder

BLUE = np.array([0x1F, 0x5F, 0xBF])
RED = np.array([0xC8, 0x35, 0x2B])


def read_video(path) -> tuple[dict, np.ndarray]:
    frames = imageio_ffmpeg.read_frames(str(path))
    meta = next(frames)
    w, h = meta["size"]
    return meta, np.stack([np.frombuffer(f, np.uint8).reshape(h, w, 3) for f in frames])


def near(frame: np.ndarray, colour: np.ndarray, tol: int = 40) -> int:
    """Pixels within ``tol`` of ``colour`` on every channel."""
    return int((np.abs(frame.astype(int) - colour).max(-1) < tol).sum())


@pytest.fixture
def walker(random_motion):
    """A 5-joint synthetic rig (Hips, Spine, Head, UpperLeg_L, LowerLeg_L) moving along +Z."""
    m = random_motion(frames=45, seed=2)
    pos = m.positions.copy()
    pos[:, 0] = np.array([0.0, 0.9, 0.0]) + np.outer(np.arange(45) / 30.0, [0.0, 0.0, 1.2])
    rot = np.zeros_like(m.rotations)
    rot[..., 0] = 1.0
    return m.replace(positions=pos, rotations=rot)


@pytest.mark.parametrize(("suffix", "fps", "count"), [(".mp4", 30.0, 45), (".gif", 25.0, 38)])
def test_writes_the_clip_in_real_time(tmp_path, walker, suffix, fps, count):
    out = render_preview(walker, tmp_path / f"walk{suffix}", captions=["happy"] * 45,
                         title="synthetic", size=(320, 240))
    meta, frames = read_video(out)
    assert frames.shape == (count, 240, 320, 3)
    assert meta["fps"] == pytest.approx(fps)
    # The left leg is drawn in blue on a white background, in every frame.
    assert all(near(f, BLUE) > 10 for f in frames)
    assert (frames[0] > 240).all(-1).mean() > 0.8
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"walk{suffix}"]


def test_lower_rate_skips_frames_and_keeps_the_duration(tmp_path, walker):
    meta, frames = read_video(render_preview(walker, tmp_path / "w.mp4", fps=10, size=(160, 128)))
    assert len(frames) == 15 and meta["fps"] == pytest.approx(10.0)


def test_the_camera_follows_the_walker(tmp_path, walker):
    pos = walker.positions.copy()
    pos[:, 0, 2] *= 20.0  # 36 m in 1.5 s: leaves any fixed view
    far = walker.replace(positions=pos)
    _, frames = read_video(render_preview(far, tmp_path / "w.mp4", size=(320, 240)))
    assert all(near(f, BLUE) > 10 for f in frames)


def test_path_is_drawn(tmp_path, walker):
    path = figure8(1.0).points
    _, with_path = read_video(render_preview(walker, tmp_path / "a.mp4", path_xz=path,
                                             size=(320, 240)))
    _, without = read_video(render_preview(walker, tmp_path / "b.mp4", size=(320, 240)))
    green = np.array([0x2A, 0x9D, 0x4B])
    assert near(with_path[0], green) > 50 and near(without[0], green) == 0


def test_bones_skip_translation_links_and_colour_sides(walker):
    sk = walker.skeleton
    pos = walker.positions_with_end_sites()
    idx, sides = bones(walker, pos)
    assert len(idx) == sk.num_joints - 1 + len(sk.end_site_parents)
    children = [int(c) for _, c in idx]
    assert sides[children.index(sk.index("UpperLeg_L"))] == "left"
    assert sides[children.index(sk.index("Spine"))] == "centre"
    # A child that slides away from its parent is a translation, not a bone.
    moved = walker.positions.copy()
    moved[:, 1, 1] += np.linspace(0, 1, walker.num_frames)
    m2 = walker.replace(positions=moved)
    idx2, _ = bones(m2, m2.positions_with_end_sites())
    assert (0, 1) not in {tuple(b) for b in idx2}


@pytest.mark.parametrize(("name", "kwargs", "words"), [
    ("w.avi", {}, "unknown video type"),
    ("missing/w.mp4", {}, "does not exist"),
    ("notes.txt/w.mp4", {}, "notes.txt is a file, not a folder"),
    ("w.mp4", {"captions": ["x"]}, "captions"),
    ("w.mp4", {"fps": 0.0}, "positive"),
])
def test_bad_requests(tmp_path, walker, name, kwargs, words):
    if name.startswith("notes.txt/"):
        (tmp_path / "notes.txt").write_text("mine")
    before = sorted(tmp_path.iterdir())
    with pytest.raises(PreviewError, match=words):
        render_preview(walker, tmp_path / name, **kwargs)
    assert sorted(tmp_path.iterdir()) == before


def test_encoder_failure_leaves_no_file(tmp_path, walker, monkeypatch):
    monkeypatch.setattr(video_mod, "_command", lambda *a: [sys.executable, "-c",
                                                             "import sys; sys.exit(3)"])
    with pytest.raises(OutputError, match=r"cannot write .*w\.mp4.*ffmpeg"):
        render_preview(walker, tmp_path / "w.mp4")
    assert list(tmp_path.iterdir()) == []


#: Runs the command after it under a file-size limit of 4 KiB, with the default action of
#: ``SIGXFSZ`` (killed), as after ``ulimit -f`` in a shell: Python ignores the signal, so it
#: is restored before ffmpeg starts.
UNDER_FILE_SIZE_LIMIT = (
    "import os, resource, signal, sys; "
    "resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096)); "
    "signal.signal(signal.SIGXFSZ, signal.SIG_DFL); os.execv(sys.argv[1], sys.argv[1:])"
)


@pytest.mark.skipif(not hasattr(signal, "SIGXFSZ"), reason="needs POSIX file-size limits")
def test_ffmpeg_stopped_by_the_file_size_limit_is_explained(tmp_path, walker, monkeypatch):
    real = video_mod._command
    monkeypatch.setattr(video_mod, "_command", lambda *a: [sys.executable, "-c",
                                                           UNDER_FILE_SIZE_LIMIT, *real(*a)])
    with pytest.raises(OutputError) as exc:
        render_preview(walker, tmp_path / "w.mp4", size=(320, 240))
    message = str(exc.value)
    assert "w.mp4" in message and "file-size limit (SIGXFSZ)" in message, message
    assert "ulimit -f" in message and "-25" not in message and "\n" not in message
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("sig", "words"), [("SIGKILL", "out of memory"),
                                            ("SIGSEGV", "run the command again")])
def test_ffmpeg_killed_by_a_signal_is_named_by_it(tmp_path, walker, monkeypatch, sig, words):
    script = f"import os, signal; os.kill(os.getpid(), signal.{sig})"
    monkeypatch.setattr(video_mod, "_command", lambda *a: [sys.executable, "-c", script])
    with pytest.raises(OutputError) as exc:
        render_preview(walker, tmp_path / "w.gif", size=(64, 64))
    message = str(exc.value)
    assert f"(ffmpeg) was stopped by signal {sig} (" in message and words in message, message
    assert "exit status" not in message
    assert list(tmp_path.iterdir()) == []


def test_an_encoder_that_exits_0_with_a_truncated_gif_is_caught(tmp_path, walker, monkeypatch):
    script = "import sys; sys.stdin.buffer.read(); open(sys.argv[1], 'wb').write(b'GIF89a')"
    monkeypatch.setattr(video_mod, "_command",
                        lambda path, *a: [sys.executable, "-c", script, str(path)])
    with pytest.raises(OutputError, match="incomplete"):
        render_preview(walker, tmp_path / "w.gif", size=(64, 64))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("suffix", [".gif", ".mp4"])
def test_a_full_disk_is_one_error_and_leaves_no_file(tmp_path, walker, monkeypatch, suffix):
    fill_disk(monkeypatch)
    with pytest.raises(OutputError, match="disk is full") as exc:
        render_preview(walker, tmp_path / f"w{suffix}", size=(64, 64))
    assert "\n" not in str(exc.value) and f"w{suffix}" in str(exc.value)
    assert list(tmp_path.iterdir()) == []


def test_a_folder_as_the_output_is_refused(tmp_path, walker):
    (tmp_path / "w.gif").mkdir()
    with pytest.raises(PreviewError, match="that is a folder"):
        render_preview(walker, tmp_path / "w.gif")


def test_frames_of_the_wrong_size_are_refused(tmp_path):
    with pytest.raises(ValueError, match="expected"), \
            VideoEncoder(tmp_path / "v.gif", (8, 8), 10.0, gif=True) as video:
        video.send(b"123")


def test_cli(tmp_path, walker, monkeypatch, capsys):
    clip = write_bvh(walker, tmp_path / "walk.bvh")
    out = tmp_path / "walk.gif"
    monkeypatch.setattr(sys, "argv", ["emotive", "preview", str(clip), "--out", str(out),
                                      "--path", "circle", "--caption", "sad", "--fps", "15",
                                      "--width", "200", "--height", "150"])
    with pytest.raises(SystemExit) as exc:
        main()
    assert exc.value.code in (0, None), capsys.readouterr().err
    _, frames = read_video(out)
    assert frames.shape[1:] == (150, 200, 3) and len(frames) == 23
    monkeypatch.setattr(sys, "argv", ["emotive", "preview", str(clip), "--out", str(out),
                                      "--path", "nowhere", "--force"])
    with pytest.raises(SystemExit) as exc:
        main()
    assert exc.value.code == 2 and "unknown path 'nowhere'" in capsys.readouterr().err
    fill_disk(monkeypatch)
    full = tmp_path / "full.gif"
    monkeypatch.setattr(sys, "argv", ["emotive", "preview", str(clip), "--out", str(full),
                                      "--width", "64", "--height", "64"])
    with pytest.raises(SystemExit) as exc:
        main()
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.startswith("error: ") and err.count("\n") == 1, err
    assert "disk is full" in err and "wrote" not in err and not full.exists()
