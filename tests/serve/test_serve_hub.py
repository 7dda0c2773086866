"""Outboxes: a client is blamed only for its own backlog, never for the server's stall."""

from __future__ import annotations

import asyncio

from emotive.serve.hub import ON_TIME_PERIODS, Outbox

PERIOD = 1.0 / 30.0


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _box(clock: Clock, stall: float = 1.0) -> Outbox:
    return Outbox(0, frames=2, max_replies=3, stall_seconds=stall, period=PERIOD, clock=clock)


def _frames(box: Outbox, clock: Clock, count: int, gap: float = PERIOD) -> None:
    for _ in range(count):
        clock.now += gap
        box.put_frame(b"f")


def test_a_client_whose_socket_takes_nothing_while_frames_come_on_time_is_stalled():
    clock = Clock()
    box = _box(clock)
    box.sending(True)
    _frames(box, clock, 29)
    assert not box.stalled.is_set() and box.dropped == 27
    _frames(box, clock, 3)
    assert box.stalled.is_set()


def test_the_servers_own_stall_never_counts_against_a_client():
    clock = Clock()
    box = _box(clock, stall=10.0)
    box.sending(True)
    # Frames come in bursts after gaps longer than ON_TIME_PERIODS (the server was late):
    # only the on-time gaps inside each burst count, 0.1 s per burst, 5 s in all.
    for _ in range(50):
        _frames(box, clock, 1, gap=(ON_TIME_PERIODS + 2) * PERIOD)
        _frames(box, clock, 3)
    assert clock.now > 14.0 and not box.stalled.is_set()
    _frames(box, clock, 160)
    assert box.stalled.is_set()


def test_a_finished_send_clears_the_backlog():
    clock = Clock()
    box = _box(clock)
    for _ in range(20):
        box.sending(True)
        _frames(box, clock, 20)
        box.sending(False)
    assert clock.now > 10.0 and not box.stalled.is_set()


def test_a_client_that_reads_is_never_stalled_however_many_frames_overflow():
    clock = Clock()
    box = _box(clock)
    _frames(box, clock, 1000)
    assert not box.stalled.is_set() and box.dropped == 998


def test_replies_are_kept_and_the_room_opens_when_one_is_read():
    clock = Clock()
    box = _box(clock)

    async def run() -> list[bool]:
        for k in range(5):
            box.put_reply({"type": "ok", "ref": k})
        waited = asyncio.ensure_future(box.room())
        await asyncio.sleep(0)
        before = waited.done()
        got = [await box.next() for _ in range(3)]
        await asyncio.wait_for(waited, 5.0)
        return [before, box.has_room(), [g["ref"] for g in got] == [0, 1, 2]]

    assert asyncio.run(run()) == [False, True, True]
    assert len(box.replies) == 2 and not box.stalled.is_set()
