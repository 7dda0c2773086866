"""``emotive serve``: one shared scene of walking agents for browsers and programs.

Checks the settings (a host other than a loopback address needs ``--token``), opens the
listening socket, loads the engine, prints the app's URLs and runs uvicorn until Ctrl-C
(:mod:`emotive.serve`; the protocol is ``docs/serve.md``). With ``--scene`` the scene's crowd
is loaded first (its file, geometry and emotions checked, JuPedSim built), so that a bad
scene fails before anything binds. The server, torch and the crowd package (JuPedSim) are
imported inside the command so that ``emotive serve --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import SeedOpt


def serve(
    host: Annotated[str, typer.Option("--host", help="Address to bind; any other than "
                                      "127.0.0.1/localhost needs --token.")] = "127.0.0.1",
    port: Annotated[int, typer.Option("--port", help="TCP port (0: any free one).")] = 8000,
    max_agents: Annotated[int, typer.Option("--max-agents", help="Agents the scene may hold "
                                            "at once (fewer where the machine cannot "
                                            "step them in time).")] = 500,
    max_agents_per_client: Annotated[int, typer.Option(
        "--max-agents-per-client", help="Agents one connection may have in the scene at "
        "once.")] = 200,
    token: Annotated[str | None, typer.Option(
        "--token", help="Secret every /api request and the websocket must present "
        "('Authorization: Bearer T' or ?token=T).", show_default=False)] = None,
    model: Annotated[str, typer.Option("--model", help="Streaming model: gait (the main "
                                       "network) or fcrbm.")] = "gait",
    backend: Annotated[str, typer.Option("--backend", help="Where the gait network runs: "
                                         "torch or onnx (ONNX Runtime).")] = "torch",
    seed: SeedOpt = 0,
    scene: Annotated[Path | None, typer.Option(
        "--scene", help="A scene file (scene.toml, docs/crowd.md): its groups spawn and "
        "navigate with JuPedSim, and clients add agents with goals and draw obstacles "
        "(needs the crowd extra).", show_default=False)] = None,
    workers: Annotated[int | None, typer.Option(
        "--workers", help="Processes stepping the scene's agents, each its share (1: step "
        "in the server's own process). Default: the cores, at most 4.",
        show_default=False)] = None,
    worker_kind: Annotated[str, typer.Option(
        "--worker-kind", help="With --workers above 1, what a worker is: threads (of the "
        "server's process), processes, or auto: threads on the torch backend, whose step "
        "releases the interpreter lock, processes on onnx.")] = "auto",
    step_budget: Annotated[float, typer.Option(
        "--step-budget", help="Share of a frame each step (of the server, or of each "
        "worker) may take with every agent admitted; beyond it new agents are refused "
        "(above 1: frames come late; for load tests).")]
    = 0.5,
    log_level: Annotated[str, typer.Option("--log-level", help="uvicorn's log level: "
                                           "critical, error, warning, info, debug.")]
    = "warning",
) -> None:
    """Serve the live scene: the browser app at /, the websocket at /ws, the API at /api."""
    from emotive.serve.errors import ServeError

    try:
        from emotive.serve.app import create_app
        from emotive.serve.server import base_url, bind, bound_port, uvicorn_server
        from emotive.serve.settings import ServeSettings, default_workers
    except ModuleNotFoundError as exc:
        raise ServeError(f"emotive serve needs the serve extra ({exc.name} is missing): "
                         "pip install 'emotive[serve]'") from None

    if workers is None:
        workers = 1 if scene is not None else default_workers()
    settings = ServeSettings(host=host, port=port, token=token, model=model, backend=backend,
                             seed=seed, scene=None if scene is None else str(scene),
                             max_agents=max_agents,
                             max_agents_per_client=max_agents_per_client,
                             workers=workers, worker_kind=worker_kind,
                             step_budget=step_budget).checked()
    engine = None
    if settings.scene is not None:
        try:
            from emotive.serve.crowd_engine import load_crowd_engine
        except ModuleNotFoundError as exc:
            raise ServeError(f"--scene needs the crowd extra ({exc.name} is missing): pip "
                             "install 'emotive[crowd]'") from None
        engine = load_crowd_engine(settings.scene, settings.seed)
    sock = bind(settings.host, settings.port)
    try:
        app = create_app(settings, engine)
        url = base_url(settings.host, bound_port(sock))
        query = f"?token={settings.token}&" if settings.token else "?"
        steppers = ("in this process" if settings.workers == 1
                    else f"by {settings.workers} worker "
                         f"{'threads' if settings.worker_threads else 'processes'}")
        typer.echo(f"emotive serve: {settings.model} on {settings.backend}, up to "
                   f"{settings.max_agents} agents ({settings.max_agents_per_client} per "
                   f"client), stepped {steppers}")
        if engine is not None:
            groups = len(engine.crowd.scene.groups)
            typer.echo(f"  scene: {settings.scene}, {groups} group(s) (they spawn whatever "
                       "--max-agents says, and count in it)")
        typer.echo(f"  app:   {url}/{query.rstrip('&?')}")
        if engine is None:
            typer.echo(f"  demo:  {url}/{query}demo=1")
        typer.echo(f"  ws:    {url.replace('http', 'ws', 1)}/ws  (protocol: docs/serve.md)")
        typer.echo("  Ctrl-C stops the server.")
        server = uvicorn_server(app, settings, log_level=log_level)
        try:
            server.run(sockets=[sock])
        except KeyboardInterrupt:
            pass
        typer.echo("emotive serve: stopped")
    finally:
        sock.close()
