"""The HTTP routes, the token on the API and the websocket, and the bind rule."""

from __future__ import annotations

import asyncio
import json

import httpx
import pygltflib
import pytest
import websockets

from emotive.serve.errors import ServeError
from emotive.serve.settings import ServeSettings, is_loopback
from emotive.serve.testing import running_server
from serve_client import REPLY_TIMEOUT, WsClient, ws_url

TOKEN = "s3cret-token"


@pytest.fixture(scope="module")
def url():
    with running_server(max_agents=20) as base:
        yield base


def test_health_and_stats(url):
    health = httpx.get(f"{url}/api/health").json()
    assert health == {"status": "ok", "version": health["version"], "model": "gait",
                      "backend": "torch", "workers": 1, "live_workers": 1,
                      "encodings": [1, 2]}
    stats = httpx.get(f"{url}/api/stats").json()
    assert {"agents", "clients", "fps", "frames", "dropped_frames", "late_frames", "step_ms",
            "tick_ms", "workers", "lost_agents", "model", "backend"} <= set(stats)
    assert set(stats["step_ms"]) == {"p50", "p99"}
    assert set(stats["tick_ms"]) == {"commands", "step", "encode", "step_cpu"}
    assert stats["workers"] == 1


def test_skeleton_describes_the_frames(url):
    sk = httpx.get(f"{url}/api/skeleton").json()
    j = len(sk["joints"])
    assert len(sk["parents"]) == len(sk["offsets"]) == j and sk["parents"][0] == -1
    assert 0 <= sk["mover"] < j and sk["fps"] == 30.0
    assert set(sk["points"]) == set(sk["labels"])
    assert all(-1 <= v <= 1 and -1 <= a <= 1 for v, a in sk["points"].values())

    async def one_frame():
        async with WsClient(url) as client:
            await client.add_agents(1)
            return (await client.frames_after(2))[-1]

    frame = asyncio.run(one_frame())
    assert frame.rotations.shape[1] == j
    assert frame.world.shape[1] == j + len(sk["end_site_parents"])
    assert frame.emotion.shape[1] == len(sk["labels"])


def test_agents_lists_the_scene(url):
    async def add():
        async with WsClient(url) as client:
            return await client.request({"type": "add_agent", "emotion": "sad", "pace": 0.8,
                                         "path": "line"})

    agent = asyncio.run(add())["id"]
    rows = {a["id"]: a for a in httpx.get(f"{url}/api/agents").json()["agents"]}
    row = rows[agent]
    assert row["emotion"] == {"sad": 1.0} and row["pace"] == 0.8
    assert row["valence"] < 0 and len(row["path"]) >= 2


def test_mannequin_has_a_bone_per_joint(url, tmp_path):
    response = httpx.get(f"{url}/api/mannequin.glb")
    assert response.status_code == 200
    assert response.headers["content-type"] == "model/gltf-binary"
    path = tmp_path / "mannequin.glb"
    path.write_bytes(response.content)
    doc = pygltflib.GLTF2().load(str(path))
    joints = httpx.get(f"{url}/api/skeleton").json()["joints"]
    assert [doc.nodes[k].name for k in doc.skins[0].joints] == joints
    assert doc.meshes and doc.meshes[0].primitives[0].attributes.JOINTS_0 is not None


def test_page_and_missing_files(url):
    page = httpx.get(f"{url}/")
    assert page.status_code in (200, 404)
    if page.status_code == 200:
        assert "html" in page.headers["content-type"]
    else:
        assert page.json()["type"] == "error"
    assert httpx.get(f"{url}/static/no-such-file.js").status_code == 404
    assert httpx.get(f"{url}/api/recordings/999").status_code == 404


def test_token_guards_the_api_and_the_websocket():
    with running_server(token=TOKEN) as base:
        assert httpx.get(f"{base}/api/health").status_code == 401
        wrong = httpx.get(f"{base}/api/stats", headers={"Authorization": "Bearer nope"})
        assert wrong.status_code == 401 and wrong.json()["type"] == "error"
        assert httpx.get(f"{base}/api/health", params={"token": TOKEN}).status_code == 200
        ok = httpx.get(f"{base}/api/skeleton", headers={"Authorization": f"Bearer {TOKEN}"})
        assert ok.status_code == 200

        async def refused(url: str) -> int:
            async with websockets.connect(url, open_timeout=REPLY_TIMEOUT) as ws:
                with pytest.raises(websockets.ConnectionClosed) as closed:
                    await ws.recv()
            return closed.value.rcvd.code

        assert asyncio.run(refused(ws_url(base))) == 4401
        assert asyncio.run(refused(ws_url(base, "wrong"))) == 4401

        async def allowed() -> dict:
            async with WsClient(base, TOKEN) as client:
                return await client.request({"type": "ping", "t": 1})

        assert asyncio.run(allowed())["type"] == "pong"


def test_other_hosts_need_a_token():
    for host in ("0.0.0.0", "192.168.1.5", "::"):
        with pytest.raises(ServeError, match="--token"):
            ServeSettings(host=host).checked()
    assert ServeSettings(host="0.0.0.0", token="t").checked().token == "t"
    assert ServeSettings(host="localhost").checked().token is None
    assert all(map(is_loopback, ("127.0.0.1", "127.8.0.1", "::1", "localhost")))
    with pytest.raises(ServeError, match="--backend onnx runs the gait"):
        ServeSettings(model="fcrbm", backend="onnx").checked()
    with pytest.raises(ServeError, match="max-agents"):
        ServeSettings(max_agents=0).checked()


def test_other_sites_are_refused(url):
    rebound = httpx.get(f"{url}/api/health", headers={"Host": "evil.example:8000"})
    assert rebound.status_code == 403 and "Host" in rebound.json()["message"]
    assert httpx.get(f"{url}/api/health", headers={"Host": "localhost"}).status_code == 200

    async def closed_with(origin: str) -> int | None:
        async with websockets.connect(ws_url(url), origin=origin,
                                      open_timeout=REPLY_TIMEOUT) as ws:
            try:
                await asyncio.wait_for(ws.recv(), REPLY_TIMEOUT)
            except websockets.ConnectionClosed as exc:
                return exc.rcvd.code
        return None

    assert asyncio.run(closed_with("http://evil.example")) == 4403
    assert asyncio.run(closed_with(url)) is None


def test_each_client_gets_the_frame_layout_it_asked_for(url):
    async def first_frames() -> dict[str, bytes]:
        got = {}
        for query in ("encoding=1", "encoding=2", ""):
            address = url.replace("http://", "ws://", 1) + "/ws" + (f"?{query}" if query else "")
            async with websockets.connect(address, max_size=None) as ws:
                await ws.send(json.dumps({"type": "add_agent"}))
                while query not in got:
                    message = await ws.recv()
                    if isinstance(message, bytes) and int.from_bytes(message[16:20], "little"):
                        got[query] = message
        address = url.replace("http://", "ws://", 1) + "/ws?encoding=3"
        async with websockets.connect(address) as ws:
            with pytest.raises(websockets.ConnectionClosed) as closed:
                await ws.recv()
        got["refused"] = closed.value.rcvd
        return got

    got = asyncio.run(first_frames())
    assert got["encoding=1"][:4] == b"EMF1" and got["encoding=2"][:4] == b"EMF2"
    assert got[""][:4] == b"EMF2"
    assert got["refused"].code == 4400 and "encoding" in got["refused"].reason
    sk = httpx.get(f"{url}/api/skeleton").json()
    assert len(sk["end_site_offsets"]) == len(sk["end_site_parents"])
