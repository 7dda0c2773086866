"""Seeded fuzzed messages and abrupt disconnects leave the server serving."""

from __future__ import annotations

import asyncio
import json
import random

import httpx
import websockets

from emotive.serve.testing import running_server
from serve_client import REPLY_TIMEOUT, WsClient, ws_url

MESSAGES = 1000
TYPES = ["add_agent", "set_emotion", "set_path", "set_target", "set_pace", "remove_agent",
         "ping", "state", "start_recording", "stop_recording", "nope", ""]
FIELDS = ["id", "path", "emotion", "schedule", "pace", "start", "target", "t", "ref", "type"]


def _value(rng: random.Random, depth: int = 0):
    pick = rng.randrange(12 if depth < 3 else 7)
    return [
        lambda: rng.randint(-3, 30), lambda: rng.uniform(-1e6, 1e6), lambda: None,
        lambda: rng.choice([True, False]), lambda: rng.choice(["circle", "sad", "happy=2",
                                                              "valence=0.3,arousal=9", "", "é"]),
        lambda: "x" * rng.randint(0, 50), lambda: rng.choice([0, -0.0, 1.5, 0.5, 1e308]),
        lambda: [_value(rng, depth + 1) for _ in range(rng.randint(0, 4))],
        lambda: [[rng.uniform(-5, 5), rng.uniform(-5, 5)] for _ in range(rng.randint(0, 4))],
        lambda: {rng.choice(FIELDS): _value(rng, depth + 1) for _ in range(rng.randint(0, 3))},
        lambda: {"happy": _value(rng, depth + 1), "sad": rng.random()},
        lambda: [{"t": _value(rng, depth + 1), "emotion": _value(rng, depth + 1)}],
    ][pick]()


def fuzzed(rng: random.Random) -> str:
    """One JSON-ish message: a mutated control message, or broken text."""
    message = {"type": rng.choice(TYPES)}
    for _ in range(rng.randint(0, 4)):
        message[rng.choice(FIELDS)] = _value(rng)
    text = json.dumps(message)
    kind = rng.random()
    if kind < 0.15:
        cut = rng.randrange(len(text))
        return text[:cut]
    if kind < 0.25:
        k = rng.randrange(len(text))
        return text[:k] + rng.choice(["{", "]", '"', "NaN", "\\u12", ",,", "\x00"]) + text[k:]
    if kind < 0.3:
        return "".join(chr(rng.randrange(1, 0x3000)) for _ in range(rng.randint(1, 40)))
    return text


def test_fuzzed_messages_and_abrupt_disconnects_leave_it_serving():
    rng = random.Random(25)
    texts = [fuzzed(rng) for _ in range(MESSAGES)]
    with running_server(rate=1e6, burst=10**6, max_agents=40) as url:

        async def run():
            async with WsClient(url) as client:
                for k in range(0, MESSAGES, 50):
                    for text in texts[k:k + 50]:
                        await client.send(text)
                    await client.wait_for(lambda k=k: len(client.replies) >= k + 50)
                for _ in range(20):
                    rude = await websockets.connect(ws_url(url), max_size=None,
                                                    open_timeout=REPLY_TIMEOUT)
                    await rude.send('{"type": "add_agent", "path": "circle"}')
                    if rng.random() < 0.5:
                        await rude.send('{"type": "add_agent", "emo')
                    rude.transport.abort()
                after = await client.frames_after(10)
                pong = await client.request({"type": "ping", "t": 1})
                return client.replies, after, pong

        replies, after, pong = asyncio.run(run())
        health = httpx.get(f"{url}/api/health").json()
        stats = httpx.get(f"{url}/api/stats").json()
    assert len(replies) >= MESSAGES
    assert {r["type"] for r in replies} <= {"error", "agent", "ok", "pong", "state",
                                            "recording"}
    assert sum(r["type"] == "error" for r in replies) > MESSAGES // 2
    assert not any("internal error" in r.get("message", "") for r in replies)
    assert len(after) == 10 and pong["type"] == "pong"
    assert health["status"] == "ok" and stats["clients"] == 0
