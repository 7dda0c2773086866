"""Recording the scene and downloading an agent as BVH or GLB."""

from __future__ import annotations

import asyncio

import httpx
import numpy as np
import pygltflib

from emotive.io.bvh import read_bvh
from emotive.serve.testing import running_server
from serve_client import WsClient, until_server

#: Frames of the server (5 scene seconds) within which a leaving client's recording stops.
LEAVE_FRAMES = 150


def test_record_and_download(tmp_path):
    with running_server() as url:

        async def run():
            async with WsClient(url) as client:
                first, second = await client.add_agents(2, path="circle")
                none = await client.request({"type": "stop_recording"})
                started = await client.request({"type": "start_recording"})
                running = httpx.get(f"{url}/api/recordings/{started['id']}")
                await client.frames_after(30)
                stopped = await client.request({"type": "stop_recording"})
                return first, second, none, started, running, stopped

        first, second, none, started, running, stopped = asyncio.run(run())
        rid = started["id"]
        bvh = httpx.get(f"{url}/api/recordings/{rid}", params={"agent": second})
        glb = httpx.get(f"{url}/api/recordings/{rid}", params={"format": "glb"})
        stranger = httpx.get(f"{url}/api/recordings/{rid}", params={"agent": 999})
        fmt = httpx.get(f"{url}/api/recordings/{rid}", params={"format": "fbx"})
        joints = httpx.get(f"{url}/api/skeleton").json()["joints"]
    assert none["type"] == "error" and "start_recording" in none["message"]
    assert started["state"] == "started" and running.status_code == 404
    assert "still running" in running.json()["message"]
    assert stopped["state"] == "stopped" and stopped["id"] == rid
    assert stopped["frames"] >= 30 and stopped["agents"] == [first, second]
    assert bvh.status_code == 200 and glb.status_code == 200
    assert stranger.status_code == 404 and fmt.status_code == 400
    path = tmp_path / "agent.bvh"
    path.write_bytes(bvh.content)
    motion = read_bvh(path)
    assert motion.num_frames == stopped["frames"] and motion.skeleton.names == tuple(joints)
    assert motion.fps == 30.0
    walked = np.linalg.norm(np.ptp(motion.positions[:, 1, [0, 2]], axis=0))
    assert walked > 0.3
    path = tmp_path / "agent.glb"
    path.write_bytes(glb.content)
    doc = pygltflib.GLTF2().load(str(path))
    assert doc.animations and [doc.nodes[k].name for k in doc.skins[0].joints] == joints


def test_limits_of_recordings():
    with running_server(recording_seconds=0.5) as url:

        async def run():
            async with WsClient(url) as client:
                await client.add_agents(1)
                started = await client.request({"type": "start_recording"})
                twice = await client.request({"type": "start_recording"})
                await client.wait_for(lambda: any("limit" in r.get("message", "")
                                                  for r in client.replies))
                stopped = await client.request({"type": "stop_recording"})
            async with WsClient(url) as leaver:
                left = await leaver.request({"type": "start_recording"})
                await leaver.frames_after(3)
            return started, twice, stopped, left, client.replies

        started, twice, stopped, left, replies = asyncio.run(run())
        notice = next(r for r in replies if "limit" in r.get("message", ""))
        assert twice["type"] == "error" and "stop_recording" in twice["message"]
        assert notice["type"] == "error" and f"recording {started['id']}" in notice["message"]
        assert stopped["frames"] == 15
        # A client that leaves stops its recording (on a later tick), which stays downloadable.
        answers = []

        def downloadable(_: dict) -> bool:
            answers.append(httpx.get(f"{url}/api/recordings/{left['id']}"))
            return answers[-1].status_code == 200

        asyncio.run(until_server(url, downloadable, lambda: "the recording of a client that "
                                 f"left is not downloadable: {answers[-1].json()}",
                                 frames=LEAVE_FRAMES))
