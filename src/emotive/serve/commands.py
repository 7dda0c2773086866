"""The simulation thread's side of control commands: fair turns, joins in spare time, quotas.

Mixed into :class:`~emotive.serve.simulation.Simulation`, whose state it shares. Commands
arrive prepared (:mod:`~emotive.serve.preparation`) with their client's work budget and wait
per client in :class:`~emotive.serve.turns.Turns`. At each tick:

* the other commands are applied in turns, one of each client a round, for at most
  :data:`COMMAND_SHARE` of a frame period (at least one), each timed and charged to its
  client's budget (seconds per second of scene time); a client over budget waits, and its
  commands with it, not the scene;
* then new agents join in one batched call (so that a hundred new agents cost one warm-up of
  the network), one waiting agent of each client a round, at most :data:`JOIN_PER_TICK`, and
  only as many as :class:`~emotive.serve.turns.JoinCosts` expects to fit in the time the tick
  has to spare before its frame is due (its own step and encoding, as they took lately,
  set aside). When not even one fits (a busy machine, a crowded scene), a batch joins anyway
  while the scene's join budget holds what it is expected to take beyond the spare time (at
  most :data:`JOIN_BURST`, the budget's size), and is charged what it took: the budget refills
  with :data:`JOIN_SHARE` of scene time, so that a stream of joins slows the scene's clock by a
  twentieth at most, one batch at a time, and an occasional one does not wait. Each client is
  charged its share of the batch.

Admission: an agent joins only if its client has fewer than ``max_agents_per_client`` in the
scene and the scene fewer than :meth:`capacity`.

A scene (``--scene``, :class:`~emotive.serve.crowd_engine.CrowdEngine`) adds agents at a point
with a goal (:class:`~emotive.serve.messages.PlaceAgent`), takes ``set_goal``,
``add_obstacle`` (every client then gets the new geometry) and ``scene``, and spawns agents
and lets them leave by its exits on its own: those are taken into the scene's agents after
each step (:meth:`SceneCommands._take_crowd`), owned by no client. Without a scene those
commands are refused.
"""

from __future__ import annotations

import contextlib
import math
import queue
from dataclasses import dataclass
from typing import Any

import numpy as np

from emotive.data.emotion import EmotionSchedule
from emotive.paths import GroundPath
from emotive.serve.capacity import StepCosts
from emotive.serve.errors import MessageError
from emotive.serve.messages import AddAgent, Command, PlaceAgent
from emotive.serve.turns import Pending, share

#: Most agents joining at one tick (100 joining took 15 ms on a 2-core machine).
JOIN_PER_TICK = 32
#: Share of a frame period the commands of one tick (joins aside) may take; the rest wait.
COMMAND_SHARE = 0.25
#: Share of scene time joins may take beyond the time ticks have to spare (a batch of gait
#: agents took 13-19 ms on the idle 2-core development machine, 100-500 ms on it at a load
#: average of 10-14: then one batch every 2-10 scene seconds).
JOIN_SHARE = 0.05
#: Seconds of joins beyond the spare time the scene's join budget holds at most.
JOIN_BURST = 0.1
#: Most points of a path reported in an agent's state.
STATE_PATH_POINTS = 200
#: Valence and arousal of an agent the scene no longer knows.
NO_VA = (0.0, 0.0)
#: Commands only a server with a scene takes.
SCENE_KINDS = ("scene", "add_obstacle", "set_goal")


@dataclass
class SceneAgent:
    """What the server knows of an agent beside the engine.

    ``path`` is ``None`` for a crowd agent, which walks where its navigation sends it.
    """

    path: GroundPath | None
    schedule: EmotionSchedule
    since: float
    pace: float
    owner: int = -1
    #: Its valence and arousal when its schedule holds one emotion, else ``None``.
    constant_va: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        self.set_schedule(self.schedule, self.since)

    def set_schedule(self, schedule: EmotionSchedule, since: float) -> None:
        """A new emotion schedule, its time 0 at scene time ``since``."""
        self.schedule, self.since = schedule, since
        if schedule is None:  # no emotion known (a stand-in in tests): neutral
            self.constant_va = NO_VA
            return
        pts = schedule.points
        self.constant_va = ((float(pts[0, 0]), float(pts[0, 1])) if len(schedule.times) == 1
                            else None)


class SceneCommands:
    """Turns, joins, admission and the replies of commands (simulation thread only)."""

    def owned(self, client: int) -> int:
        """Agents client ``client`` has in the scene (any thread: a read of one number)."""
        return self._owned.get(client, 0)

    def capacity(self) -> int:
        """Agents the scene admits now: ``max_agents``, or fewer by the measured step time."""
        return self._capacity

    def _measured(self, agents: int, seconds: float, shard: int = 0) -> None:
        """Take one step's time (of the engine stepping part ``shard``) into the limit."""
        costs = self._costs.get(shard)
        if costs is None:
            costs = self._costs[shard] = StepCosts(self.settings.step_budget / self.fps,
                                                   self.settings.max_agents)
        costs.measured(agents, seconds)
        self._update_capacity()

    def _update_capacity(self) -> None:
        limits = sum(c.limit for c in self._costs.values())
        self._capacity = min(self.settings.max_agents, limits) if self._costs else (
            self.settings.max_agents)

    def _apply_pending(self, due: float | None = None) -> None:
        """Apply the commands that came since the last tick, then join what fits.

        Args:
            due: clock time the tick's frame is due (``None``: no limit on the joins' time,
                for a caller outside the thread's loop).
        """
        while True:
            try:
                self._turns.put(Pending(*self._queue.get_nowait()))
            except queue.Empty:
                break
        deadline = self._clock() + COMMAND_SHARE / self.fps
        applied = 0
        while applied == 0 or self._clock() < deadline:
            item = self._turns.next_command()
            if item is None:
                break
            self._apply(item)
            applied += 1
        spare = math.inf if due is None else due - self._clock() - self._tick_guess
        self._join(spare)
        self._check_lost()

    def _apply(self, item: Pending) -> None:
        start = self._clock()
        try:
            reply = self._reply(item.command, item.client)
        except Exception as exc:  # every failure becomes this message's error reply
            item.future.set_exception(exc)
        else:
            item.future.set_result(reply)
        item.charge(self._clock() - start)
        self._check_lost()

    def _join(self, spare: float) -> None:
        """Join a batch of waiting agents within ``spare`` seconds, or on the join budget."""
        if not self._turns.joining():
            return
        count = self._join_costs.fitting(spare, JOIN_PER_TICK)
        if count == 0:
            count = JOIN_PER_TICK
            beyond = self._join_costs.estimate(count) - max(spare, 0.0)
            if not self._join_budget.allowed(min(beyond, JOIN_BURST)):
                return
        start = self._clock()
        self._add(self._turns.joins(count))
        self._join_budget.charge(self._clock() - start - max(spare, 0.0))

    def _refusal(self, client: int, taken: dict[int, int], count: int) -> MessageError | None:
        """Why one more agent of ``client`` may not join a scene of ``count``, or ``None``."""
        s = self.settings
        if client >= 0 and self.owned(client) + taken.get(client, 0) >= s.max_agents_per_client:
            return MessageError(
                f"you have {self.owned(client)} agents in the scene, the limit per client "
                f"(--max-agents-per-client {s.max_agents_per_client}): remove some first")
        if count < self._capacity:
            return None
        if self._capacity >= s.max_agents:
            return MessageError(f"the scene holds {count} agents, the server's limit "
                                f"(--max-agents {s.max_agents}): remove agents first")
        return MessageError(
            f"the scene holds {count} agents, the most this machine steps within "
            f"{100 * s.step_budget:.0f} % of a {1000 / self.fps:.1f} ms frame by its measured "
            f"step time (limit now {self._capacity}, below --max-agents {s.max_agents}): "
            "remove agents first, or try again when the machine is less busy")

    def _add(self, batch: list[Pending]) -> None:
        """Add ``add_agent`` commands in one call, within the quotas and the capacity."""
        taken: dict[int, int] = {}
        admitted = []
        for item in batch:
            refusal = self._refusal(item.client, taken, len(self.engine) + len(admitted))
            if refusal is not None:
                item.future.set_exception(refusal)
                continue
            taken[item.client] = taken.get(item.client, 0) + 1
            admitted.append(item)
        if not admitted:
            return
        specs: list[AddAgent | PlaceAgent] = [item.command.value for item in admitted]
        start = self._clock()
        try:
            ids = self._engine_add(specs)
        except Exception as exc:  # every failure becomes this message's error reply
            share(admitted, self._clock() - start)
            if len(admitted) == 1:
                admitted[0].future.set_exception(exc)
                return
            # One bad entry spoils a batch: add one at a time, each with its own reply.
            for item in admitted:
                self._add([item])
            return
        seconds = self._clock() - start
        self._join_costs.measured(len(admitted), seconds)
        share(admitted, seconds)
        now = self.frames / self.fps
        for agent, spec, item in zip(ids, specs, admitted, strict=True):
            self._emotions += 1
            self._agents[agent] = SceneAgent(getattr(spec, "path", None), spec.schedule, now,
                                             spec.pace, item.client)
            self._owned[item.client] = self._owned.get(item.client, 0) + 1
            item.future.set_result({"type": "agent", "id": agent})

    def _engine_add(self, specs: list[AddAgent | PlaceAgent]) -> list[int]:
        """The engine's ids of new agents: on their paths, or placed with goals (a scene)."""
        if any(isinstance(s, PlaceAgent) for s in specs):
            place = getattr(self.engine, "place_agents", None)
            if place is None:
                raise MessageError('"at" and "goal" add a crowd agent, which needs a scene: '
                                   'start the server with --scene SCENE.toml, or give "path"')
            return place(specs)
        return self.engine.add_agents([s.path for s in specs], [s.schedule for s in specs],
                                      [s.start for s in specs], [s.pace for s in specs])

    def _take_crowd(self) -> None:
        """Take in the agents a scene spawned and forget those that left by its exits."""
        take = getattr(self.engine, "take_changes", None)
        if take is None:
            return
        joined, left = take()
        now = self.frames / self.fps
        for agent, schedule, pace in joined:
            self._agents[agent] = SceneAgent(None, schedule, now, pace)
            self._owned[-1] = self._owned.get(-1, 0) + 1
        for agent in left:
            info = self._agents.pop(agent, None)
            if info is not None:
                self._owned[info.owner] = self._owned.get(info.owner, 1) - 1
        self._emotions += bool(joined or left)

    def _scene_reply(self, command: Command) -> dict[str, Any]:
        """The reply to a command of :data:`SCENE_KINDS`."""
        if getattr(self.engine, "scene_message", None) is None:
            raise MessageError(f'"{command.kind}" needs a scene: start the server with '
                               "--scene SCENE.toml")
        if command.kind == "scene":
            return dict(self.engine.scene_message)
        if command.kind == "set_goal":
            self.engine.set_goal(self._known(command.agent), command.value)
            return {"type": "ok"}
        number = self.engine.add_obstacle(command.value)
        self.sink.notice(None, dict(self.engine.scene_message))
        return {"type": "obstacle", "index": number,
                "version": self.engine.scene_message["version"]}

    def _known(self, agent: int | None) -> int:
        if agent not in self._agents:
            raise MessageError(f"no agent with id {agent}: it was never added or was removed "
                               '(send {"type": "state"} for the live ones)')
        return int(agent)

    def _reply(self, command: Command, client: int) -> dict[str, Any]:
        kind, value = command.kind, command.value
        if kind == "state":
            return {"type": "state", "agents": self.agent_states()}
        if kind == "start_recording":
            rec = self.recorder.start(client)
            return {"type": "recording", "id": rec.rid, "state": "started"}
        if kind == "client_left":
            self.recorder.release(client)
            return {"type": "ok"}
        if kind == "stop_recording":
            rec = self.recorder.stop(client, value)
            return {"type": "recording", "id": rec.rid, "state": "stopped",
                    "frames": rec.frames, "agents": rec.agents}
        if kind in SCENE_KINDS:
            return self._scene_reply(command)
        agent = self._known(command.agent)
        info = self._agents[agent]
        if kind == "remove_agent":
            self.engine.remove_agent(agent)
            del self._agents[agent]
            self._emotions += 1
            self._owned[info.owner] = self._owned.get(info.owner, 1) - 1
        elif kind == "set_emotion":
            self.engine.set_emotion(agent, value)
            info.set_schedule(value, self.frames / self.fps)
            self._emotions += 1
        elif kind == "set_path":
            self.engine.set_path(agent, value)
            info.path = value
        elif kind == "set_target":
            path = self.engine.set_target(agent, value)
            if path is not None:  # step workers answer with it later (_tick)
                info.path = path
        elif kind == "set_pace":
            self.engine.set_pace(agent, value)
            info.pace = value
        else:
            raise MessageError(f"unknown command {kind!r}")
        return {"type": "ok"}

    def agent_states(self) -> list[dict[str, Any]]:
        """Every live agent's state, as ``GET /api/agents`` reports it (simulation thread)."""
        frame = self._last
        rows = {a: k for k, a in enumerate(frame.agents)}
        labels = self.engine.labels
        worker_of = getattr(self.engine, "worker_of", None)
        out = []
        for agent, info in self._agents.items():
            k = rows.get(agent)
            weights = (frame.emotion[k] if k is not None else info.schedule.at(0.0))
            va = self._va[k] if k is not None and k < len(self._va) else info.schedule.points[0]
            out.append({
                "id": agent,
                "emotion": {n: round(float(w), 4) for n, w in zip(labels, weights, strict=True)
                            if w > 1e-4},
                "valence": round(float(va[0]), 4), "arousal": round(float(va[1]), 4),
                "pace": info.pace,
            })
            if info.path is None:
                out[-1].update(self.engine.agent_state(
                    agent, None if k is None else frame.root[k]))
                continue
            pts = info.path.points
            step = max(1, math.ceil(len(pts) / STATE_PATH_POINTS))
            path = np.vstack((pts[::step], pts[-1:])) if (len(pts) - 1) % step else pts[::step]
            out[-1]["path"] = np.round(path, 3).tolist()
            if worker_of is not None:
                with contextlib.suppress(KeyError):  # its worker was just lost
                    out[-1]["worker"] = worker_of(agent)
        return out
