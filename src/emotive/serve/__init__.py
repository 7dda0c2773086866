"""``emotive serve``: one shared scene of walking agents, streamed to browsers and programs.

The protocol (routes, control messages, the binary frame layouts) is documented in
``docs/serve.md``. Modules, bottom to top: :mod:`~emotive.serve.errors` (typed errors),
:mod:`~emotive.serve.settings` (the server's limits and the bind rule),
:mod:`~emotive.serve.quantize` (the compact frame's number codes),
:mod:`~emotive.serve.frames` (the binary frame layouts, versions 1 and 2),
:mod:`~emotive.serve.rig` (world positions from a frame's rotations),
:mod:`~emotive.serve.limits` (message size, nesting depth, rate),
:mod:`~emotive.serve.messages` (control messages into commands),
:mod:`~emotive.serve.engines` (one adapter over the gait and FCRBM streaming generators),
:mod:`~emotive.serve.crowd_engine` (a scene's crowd as the engine, ``--scene``; imported only
then),
:mod:`~emotive.serve.worker_process` (a step worker's side: its requests and frame block),
:mod:`~emotive.serve.shards` (the server's handles on its step workers, threads or
processes), :mod:`~emotive.serve.workers` (the scene split over step workers),
:mod:`~emotive.serve.capacity` (the admission limit from measured step times),
:mod:`~emotive.serve.recording` (recorded frames into motions),
:mod:`~emotive.serve.simulation` (the thread that drives the engine on its clock),
:mod:`~emotive.serve.hub` (per-client outboxes), :mod:`~emotive.serve.preparation` (control
messages prepared off the event loop and the simulation thread),
:mod:`~emotive.serve.session` (one websocket
connection), :mod:`~emotive.serve.app` (the ASGI app), :mod:`~emotive.serve.server` (uvicorn)
and :mod:`~emotive.serve.testing` (a live server for tests).

Nothing is imported here, so ``emotive serve --help`` stays light.
"""
