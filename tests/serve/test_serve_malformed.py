"""Every malformed or invalid message gets an error reply while the frames keep coming."""

from __future__ import annotations

import asyncio
import contextlib
import json

import httpx
import pytest
import websockets

from emotive.serve.testing import running_server
from serve_client import WsClient

BAD_TEXT = [
    ("not json at all", "not JSON"),
    ("{}", '"type"'),
    ('"just a string"', "JSON object"),
    ('{"type": "teleport"}', "unknown message type"),
    ('{"type": "add_agent", "emotion": {"happy": NaN}}', "NaN"),
    ('{"type": "add_agent", "emotion": {"happy": 1e400}}', "out of range"),
    ('{"type": "add_agent", "path": [[0, 0]]}', "at least two"),
    ('{"type": "add_agent", "path": [[0, 0], [NaN, 1]]}', "NaN"),
    ('{"type": "add_agent", "emotion": "furious"}', "furious"),
    ('{"type": "add_agent", "emotion": "/etc/passwd"}', "not an emotion"),
    ('{"type": "set_emotion", "id": 987654, "emotion": "sad"}', "no agent with id 987654"),
    ('{"type": "remove_agent", "id": 987654}', "no agent with id 987654"),
    ('{"type": "set_target", "id": 987654, "target": [1, 1]}', "no agent with id 987654"),
    ('{"type": "set_pace", "id": 0, "pace": 9}', "between"),
    ('{"type": "stop_recording"}', "no recording"),
    ("[" * 10_000 + "]" * 10_000, "10000 levels"),
    ('{"type": "ping", "pad": "' + "x" * 1_500_000 + '"}', "larger than the limit"),
]


@pytest.fixture(scope="module")
def url():
    with running_server(max_agents=3) as base:
        yield base


async def _errors(client: WsClient, messages: list[tuple[str, str]]) -> list[str]:
    """Send each message alone and return the error reply each got."""
    texts = []
    for text, _ in messages:
        before = len(client.replies)
        await client.send(text)
        await client.wait_for(lambda b=before: len(client.replies) > b)
        reply = client.replies[before]
        assert reply["type"] == "error", (text[:60], reply)
        texts.append(reply["message"])
    return texts


def test_each_bad_message_gets_an_error_and_the_stream_goes_on(url):
    async def run():
        async with WsClient(url) as client:
            await client.add_agents(1)
            await client.frames_after(2)
            start = len(client.frames)
            texts = await _errors(client, BAD_TEXT)
            count = len(client.replies)
            await client.ws.send(b"\x00binary")
            await client.wait_for(lambda: len(client.replies) > count)
            binary = client.replies[count]["message"]
            after = await client.frames_after(5)
            pong = await client.request({"type": "ping", "t": 12.5})
            return texts, binary, len(client.frames) - start, after, pong

    texts, binary, during, after, pong = asyncio.run(run())
    for (text, match), message in zip(BAD_TEXT, texts, strict=True):
        assert match in message, (text[:60], message)
    assert "binary" in binary
    assert during > 5 and len(after[-1].ids) >= 1
    assert pong["type"] == "pong" and pong["t"] == 12.5 and pong["server_time"] > 0
    assert httpx.get(f"{url}/api/health").json()["status"] == "ok"


def test_errors_echo_the_ref(url):
    async def run():
        async with WsClient(url) as client:
            return await client.request({"type": "remove_agent", "id": -5})

    reply = asyncio.run(run())
    assert reply["type"] == "error" and reply["ref"].startswith("r")


def _replies(url: str, texts: list[str]) -> list[dict]:
    """Send every text on one connection; the replies, once there is one for each."""
    async def run():
        async with WsClient(url) as client:
            for text in texts:
                await client.send(text)
            await client.wait_for(lambda: len(client.replies) >= len(texts))
            return client.replies

    return asyncio.run(run())


def test_errors_to_messages_holding_nan_or_infinity_echo_the_ref(url):
    texts = ['{"type": "add_agent", "pace": NaN, "ref": "nan"}',
             '{"type": "set_target", "id": 0, "target": [Infinity, 0], "ref": {"k": 1}}',
             '{"type": "add_agent", "path": [[0, 0], [1e999, 1]], "ref": 7, "pad": "'
             + "x" * 5000 + '"}']
    replies = _replies(url, texts)
    assert all(r["type"] == "error" and "finite numbers" in r["message"] for r in replies)
    assert sorted(map(str, (r["ref"] for r in replies))) == ["7", "nan", "{'k': 1}"]


def test_refusals_of_messages_too_large_to_read_echo_a_ref_sent_first(url):
    texts = ['{"ref": "big", "type": "ping", "pad": "' + "x" * 1_500_000 + '"}',
             '{"ref": "many", "type": "add_agent", "path": [' + "[0, 0], " * 20_000 + "[1, 1]]}",
             '{"ref": "deep", "type": "ping", "pad": ' + "[" * 100 + "]" * 100 + "}"]
    replies = _replies(url, texts)
    assert all(r["type"] == "error" for r in replies), replies
    assert sorted(r.get("ref") for r in replies) == ["big", "deep", "many"], replies


def test_agents_beyond_the_limit_are_refused(url):
    async def run():
        async with WsClient(url) as client:
            state = await client.request({"type": "state"})
            for agent in state["agents"]:
                await client.request({"type": "remove_agent", "id": agent["id"]})
            return await client.requests([{"type": "add_agent"}] * 5)

    replies = asyncio.run(run())
    assert [r["type"] for r in replies] == ["agent"] * 3 + ["error"] * 2
    assert "--max-agents 3" in replies[-1]["message"]


def test_a_burst_past_the_rate_limit_is_answered_not_applied(url):
    async def run():
        async with WsClient(url) as client:
            for k in range(260):
                await client.send(json.dumps({"type": "ping", "t": k}))
            await client.wait_for(lambda: len(client.replies) >= 260)
            await client.frames_after(3)
            return client.replies

    replies = asyncio.run(run())
    kinds = [r["type"] for r in replies]
    assert kinds.count("pong") >= 200 and kinds.count("error") >= 40
    assert all("too many messages" in r["message"] for r in replies if r["type"] == "error")


def test_a_far_too_large_message_closes_only_its_connection(url):
    async def run():
        async with WsClient(url) as other:
            async with WsClient(url) as client:
                # The server may close while the message is still being sent.
                with contextlib.suppress(websockets.ConnectionClosed):
                    await client.send('{"type": "ping", "pad": "' + "x" * 3_000_000 + '"}')
                await client.wait_for(lambda: client.ws.close_code is not None)
                code = client.ws.close_code
            more = await other.frames_after(5)
            pong = await other.request({"type": "ping"})
            return code, more, pong

    code, more, pong = asyncio.run(run())
    # 1009 (message too big); 1006 when the reset of the socket beats the close frame.
    assert code in (1009, 1006)
    assert len(more) == 5 and pong["type"] == "pong"
