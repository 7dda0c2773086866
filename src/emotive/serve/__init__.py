"""``emotive serve``: one shared scene of walking agents, streamed to browsers and programs.

The protocol (routes, control messages, the binary frame layout) is documented in
``docs/serve.md``. Modules, bottom to top: :mod:`~emotive.serve.errors` (typed errors),
:mod:`~emotive.serve.settings` (the server's limits and the bind rule),
:mod:`~emotive.serve.frames` (the binary frame layout), :mod:`~emotive.serve.limits` (message
size, nesting depth, rate), :mod:`~emotive.serve.messages` (control messages into commands),
:mod:`~emotive.serve.engines` (one adapter over the gait and FCRBM streaming generators),
:mod:`~emotive.serve.recording` (recorded frames into motions),
:mod:`~emotive.serve.simulation` (the thread that owns the engine and its clock),
:mod:`~emotive.serve.hub` (per-client outboxes), :mod:`~emotive.serve.preparation` (control
messages prepared off the event loop and the simulation thread),
:mod:`~emotive.serve.session` (one websocket
connection), :mod:`~emotive.serve.app` (the ASGI app), :mod:`~emotive.serve.server` (uvicorn)
and :mod:`~emotive.serve.testing` (a live server for tests).

Nothing is imported here, so ``emotive serve --help`` stays light.
"""
