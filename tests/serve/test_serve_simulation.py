"""The simulation thread's clock: steady ticks, late frames counted, no bursts, no crash."""

from __future__ import annotations

import time

import numpy as np

from emotive.models.gait.generate import GaitFrame
from emotive.serve.frames import decode_frame
from emotive.serve.settings import ServeSettings
from emotive.serve.simulation import Simulation


class FakeEngine:
    """One agent standing still; each step takes ``seconds`` and may raise."""

    fps = 30.0
    labels = ("happy", "sad")
    mover = 0

    def __init__(self, seconds: float = 0.0, fail_every: int = 0, stall_at: int = 0) -> None:
        self.seconds = seconds
        self.fail_every = fail_every
        self.stall_at = stall_at
        self.steps = 0

    def __len__(self) -> int:
        return 1

    def step(self) -> GaitFrame:
        self.steps += 1
        if self.fail_every and self.steps % self.fail_every == 0:
            raise RuntimeError("model exploded")
        time.sleep(0.5 if self.steps == self.stall_at else self.seconds)
        return GaitFrame((0,), np.tile([1.0, 0, 0, 0], (1, 3, 1)), np.zeros((1, 3, 3)),
                         np.zeros((1, 4, 3)), np.array([[1.0, 0.0]]), np.zeros((1, 2)))


class Collect:
    def __init__(self) -> None:
        self.frames: list[bytes] = []
        self.times: list[float] = []

    def frame(self, data: bytes) -> None:
        self.frames.append(data)
        self.times.append(time.perf_counter())

    def notice(self, client: int, message: dict) -> None:
        raise AssertionError("no notices expected")


def _run(engine: FakeEngine, seconds: float) -> tuple[Simulation, Collect, float]:
    """Run a simulation for about ``seconds``; returns it, its frames and the seconds run."""
    sink = Collect()
    sim = Simulation(engine, ServeSettings(), sink)
    start = time.perf_counter()
    sim.start()
    time.sleep(seconds)
    sim.stop()
    return sim, sink, time.perf_counter() - start


def test_ticks_follow_the_clock_and_frames_count_up():
    sim, sink, seconds = _run(FakeEngine(), 1.0)
    assert 0.6 * 30 * seconds <= len(sink.frames) <= 30 * seconds + 2
    numbers = [decode_frame(f).number for f in sink.frames]
    assert numbers == list(range(len(numbers)))
    assert decode_frame(sink.frames[-1]).time == numbers[-1] / 30.0
    assert sim.stats()["frames"] == len(sink.frames)


def test_a_slow_engine_makes_late_frames():
    sim, _, _ = _run(FakeEngine(seconds=0.05), 1.0)
    stats = sim.stats()
    assert stats["late_frames"] >= stats["frames"] - 2
    assert stats["step_ms"]["p50"] >= 50


def test_after_a_stall_the_clock_skips_ahead_instead_of_bursting():
    sim, sink, _ = _run(FakeEngine(stall_at=5), 1.5)
    gaps = np.diff(sink.times[5:15])
    # Catching up on the 15 missed ticks would send them back to back (gaps near 0).
    assert (gaps < 0.005).sum() <= 3, gaps
    assert sim.stats()["late_frames"] >= 1


def test_an_engine_failure_does_not_end_the_stream():
    _, sink, seconds = _run(FakeEngine(fail_every=3), 1.0)
    assert len(sink.frames) >= 0.6 * 30 * seconds
    assert all(decode_frame(f).ids.tolist() == [0] for f in sink.frames)
