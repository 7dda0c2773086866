"""The simulation thread's clock: steady ticks, late frames counted, no bursts, no crash.

Each run lasts until the sink got a number of frames, not a span of wall time; the exact due
times of the ticks are checked on a virtual clock, which only the thread's own waits advance.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np

from emotive.models.gait.generate import GaitFrame
from emotive.serve.frames import DEFAULT_ENCODING, decode_frame
from emotive.serve.settings import ServeSettings
from emotive.serve.simulation import Simulation

#: Wall seconds without a new frame that count as a hang.
STALL_SECONDS = 120.0


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
    def __init__(self, clock: Callable[[], float] = time.perf_counter) -> None:
        self.frames: list[bytes] = []
        self.times: list[float] = []
        self.clock = clock

    def encodings(self) -> frozenset[int]:
        return frozenset({DEFAULT_ENCODING})

    def frame(self, data: dict[int, bytes]) -> None:
        self.frames.append(data[DEFAULT_ENCODING])
        self.times.append(self.clock())

    def notice(self, client: int | None, message: dict) -> None:
        raise AssertionError("no notices expected")


class VirtualTime:
    """A clock advanced only by the waits of the simulation thread, up to ``horizon``.

    It stands in for the thread's stop event: ``wait(s)`` moves the clock on by ``s`` at once;
    a wait past ``horizon`` blocks until the simulation stops.
    """

    def __init__(self, horizon: float) -> None:
        self.now = 0.0
        self.horizon = horizon
        self._stop = threading.Event()
        self.parked = threading.Event()

    def clock(self) -> float:
        return self.now

    def is_set(self) -> bool:
        return self._stop.is_set()

    def set(self) -> None:
        self._stop.set()

    def wait(self, seconds: float) -> bool:
        if self.now + seconds > self.horizon:
            self.parked.set()
            return self._stop.wait()
        self.now += seconds
        return self._stop.is_set()


def _run(engine: FakeEngine, frames: int) -> tuple[Simulation, Collect, float]:
    """Run a simulation until its sink got ``frames`` frames; returns it, its frames and the
    wall seconds run."""
    sink = Collect()
    sim = Simulation(engine, ServeSettings(), sink)
    start = moved = time.perf_counter()
    sim.start()
    seen = 0
    while len(sink.frames) < frames:
        now = time.perf_counter()
        if len(sink.frames) != seen:
            seen, moved = len(sink.frames), now
        assert now - moved < STALL_SECONDS, (
            f"no progress: {seen} of {frames} frames, none for {STALL_SECONDS:.0f} s")
        time.sleep(0.01)
    sim.stop()
    return sim, sink, time.perf_counter() - start


def test_ticks_fall_due_at_t0_plus_k_over_fps():
    clock = VirtualTime(horizon=1.0 + 0.5 / 30)
    sink = Collect(clock.clock)
    sim = Simulation(FakeEngine(), ServeSettings(), sink, clock=clock.clock)
    sim._stop = clock  # the thread's waits advance the virtual clock
    sim.start()
    assert clock.parked.wait(STALL_SECONDS), "no progress: the thread never reached the horizon"
    sim.stop()
    # Ticks 0..30 of the virtual second, each exactly on time.
    np.testing.assert_allclose(sink.times, np.arange(31) / 30.0, atol=1e-9)
    assert [decode_frame(f).number for f in sink.frames] == list(range(31))
    stats = sim.stats()
    assert stats["frames"] == 31 and stats["late_frames"] == 0


def test_ticks_follow_the_clock_and_frames_count_up():
    sim, sink, seconds = _run(FakeEngine(), 30)
    # Never ahead of the clock: 30 frames take at least 29 periods.
    assert len(sink.frames) <= 30 * seconds + 2
    numbers = [decode_frame(f).number for f in sink.frames]
    assert numbers == list(range(len(numbers)))
    assert decode_frame(sink.frames[-1]).time == numbers[-1] / 30.0
    assert sim.stats()["frames"] == len(sink.frames)


def test_a_slow_engine_makes_late_frames():
    sim, _, _ = _run(FakeEngine(seconds=0.05), 20)
    stats = sim.stats()
    assert stats["late_frames"] >= stats["frames"] - 2
    assert stats["step_ms"]["p50"] >= 50


def test_after_a_stall_the_clock_skips_ahead_instead_of_bursting():
    sim, sink, _ = _run(FakeEngine(stall_at=5), 20)
    gaps = np.diff(sink.times[5:15])
    # Catching up on the 15 missed ticks would send them back to back (gaps near 0).
    assert (gaps < 0.005).sum() <= 3, gaps
    assert sim.stats()["late_frames"] >= 1


def test_an_engine_failure_does_not_end_the_stream():
    engine = FakeEngine(fail_every=3)
    _, sink, _ = _run(engine, 30)
    # Every third step failed (ten of them at least) and the stream went on past them.
    assert engine.steps >= 30
    assert all(decode_frame(f).ids.tolist() == [0] for f in sink.frames)
