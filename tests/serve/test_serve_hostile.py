"""26 hostile connections for 20 s while one client watches (``serve_hostile.py``).

The campaign floods ``add_agent`` (built-in and 10,000-point paths, and agents added and
removed again, every one a join), 20,000-keyframe schedules, 256-keyframe blended schedules
at the rate limit, text that is not JSON, NaN/Infinity and out-of-range messages, and opens a
client that never reads and one that reads two messages a second; the server, its own
process, runs with two step workers and a quota of :data:`QUOTA` agent per connection.

What the design guarantees, and is asserted, in terms of the server's own frames (their
numbers, ``/api/stats``), so that it holds on a busy machine: the watcher is never closed; in
every wall second of the flood it gets every frame the scene made but :data:`SLACK` (the two
its outbox may drop, and one for an event loop the machine held up): the attackers take their
budgets of scene time, never the watcher's frames; the scene makes at least :data:`RATIO` of
the frames a second during the flood that it made without attackers in the same run, on the same
machine, just before the flood and just after it (the lower of the two: a machine whose other
load grew meanwhile slows both; each client's work is budgeted per second of scene time,
joins beyond the time ticks have to spare take a twentieth of it, preparation runs while the
scene waits), and after the flood at least half its rate before; the slow readers are
closed by their unread backlog, counted in frames, within the flood; every other hostile
message gets its reply, with its ``ref``; the server's memory grows by less than
:data:`RSS_GROWTH_MB` (printed). The absolute rate (25 frames in every second, which only an
idle machine makes) is checked by ``python -m bench.bench_hostile``.
"""

from __future__ import annotations

from serve_hostile import BLEND, CHURN, DEAF, KINDS, SLOW, campaign

#: Agents per hostile connection.
QUOTA = 1
#: Seconds of flood.
SECONDS = 20.0
#: Share of its quiet frame rate the scene keeps during the flood.
RATIO = 0.8
#: Growth of the server's resident memory over the flood, MB, at most.
RSS_GROWTH_MB = 150.0
#: Frames a second the watcher may miss: the two its outbox may drop, and one more.
SLACK = 3
#: The 1008 close of a slow reader, or, when the close could not reach it, the cut connection.
SLOW_CLOSES = (1008, 1006)


def test_hostile_connections_do_not_slow_the_scene_or_the_watcher():
    result = campaign(SECONDS, quiet=1.5, server_args=(
        "--max-agents-per-client", str(QUOTA), "--max-agents", "100", "--workers", "2"))
    floods = result["floods"]
    growth = result["rss_after_mb"] - result["rss_before_mb"]
    quiet = min(result["quiet_fps"], result["quiet_after_fps"])
    print(f"hostile: quiet {result['quiet_fps']:.1f} frames/s before, "
          f"{result['quiet_after_fps']:.1f} after, flood {result['flood_fps']:.1f}; "
          f"watcher per second {result['per_second']}; slow readers closed after "
          f"{result['slow_closed_after']} frames; RSS {result['rss_before_mb']:.0f} MB, peak "
          f"{result['rss_peak_mb']:.0f}, after {result['rss_after_mb']:.0f} (+{growth:.0f})")
    assert result["closed"] is None and result["watch_error"] is None, result
    got, made = result["per_second"], result["made_per_second"]
    told = (f"the watcher got {got} frames in the seconds of the flood, of {made} made; the "
            f"server made {result['quiet_fps']:.1f} a second before it, "
            f"{result['flood_fps']:.1f} during it and {result['quiet_after_fps']:.1f} after it")
    assert all(g >= m - SLACK for g, m in zip(got, made, strict=True)), told
    assert result["flood_fps"] >= RATIO * quiet, told
    assert result["quiet_after_fps"] >= 0.5 * result["quiet_fps"], told
    slow = [c for c in floods if c["kind"] in (DEAF, SLOW)]
    assert all(c["closed"] in SLOW_CLOSES for c in slow), slow
    assert result["slow_clients"] == len(slow) and result["slow_closed_after"] is not None
    for counts in (c for c in floods if c["kind"] not in (DEAF, SLOW)):
        assert counts["closed"] is None, counts
        assert counts["replies"] == counts["sent"], counts
        # Every message carries its ref back, the 20,000-keyframe schedule (refused by its
        # size before it is read) too: its ref comes first.
        assert counts["answered"] == counts["with_ref"], counts
    adders = [c for c in floods if c["kind"] <= 5]
    assert all(c["agents"] <= QUOTA for c in adders), adders
    refused = [c for c in adders if c["sent"] > QUOTA]
    assert refused and all(c["errors"] == c["sent"] - c["agents"] for c in refused), refused
    assert any("--max-agents-per-client" in m for c in refused for m in c["messages"])
    assert any("keyframes" in m or "values" in m for c in floods if c["kind"] == 6
               for m in c["messages"])
    # Blended schedules are applied (their own agent, then each an ``ok``) as their budget
    # allows; the churn's agents joined (and left again), as the scene's time allowed.
    blends = [c for c in floods if c["kind"] == BLEND]
    assert all(c["sent"] > 2 and c["agents"] == 1 for c in blends), blends
    churn = [c for c in floods if c["kind"] == CHURN]
    assert all(c["agents"] >= 1 for c in churn), churn
    assert len(blends) == KINDS.count(BLEND) and len(churn) == KINDS.count(CHURN)
    assert growth < RSS_GROWTH_MB, result
