"""``station serve``: the station as a service (registered through the ``station.cli`` entry point).

It keeps running until Ctrl-C (or SIGTERM), which shuts down cleanly: a running session is aborted
(the robot stopped through its latched ``stop()``, the open prompt cancelled), recorded as
``interrupted`` (resume it through the API), and the devices are closed.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from station.commands import SubParsers
from station.commands.run import add_record_options
from station.config import ConfigurationError
from station.record import RecordError

log = logging.getLogger(__name__)

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8465


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "serve",
        help="run the station as a service: REST API, live events, operator page",
        description="Serve the station's API and operator page until Ctrl-C. Prints the page's URL (with a "
        "new token when neither the configuration nor STATION_API_TOKEN sets one) on stdout.",
    )
    where = p.add_mutually_exclusive_group()
    where.add_argument("--sim", action="store_true", help="the simulated station")
    where.add_argument("--config", metavar="FILE", help="a station configuration (TOML)")
    p.add_argument(
        "--manual-prompts",
        action="store_true",
        help="with --sim: a person answers the table prompts in the page (no simulated operator)",
    )
    p.add_argument(
        "--host", default=DEFAULT_HOST, help=f"address to bind (default {DEFAULT_HOST}: this machine only)"
    )
    p.add_argument(
        "--port", type=int, default=DEFAULT_PORT, help=f"TCP port (default {DEFAULT_PORT}; 0: any free)"
    )
    add_record_options(p)
    p.set_defaults(func=lambda args: serve(p, args))


def serve(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    import uvicorn

    from api import Access, ServiceSettings, StationService, create_app, is_loopback, resolve_token

    if args.manual_prompts and not args.sim:
        parser.error(
            "--manual-prompts needs --sim (a configured station's prompts are answered in the page anyway)"
        )
    if not 0 <= args.port <= 65535:
        parser.error(f"--port must be 0-65535, got {args.port}")
    settings = ServiceSettings(
        sim=args.sim,
        manual_prompts=args.manual_prompts,
        config=Path(args.config) if args.config else None,
        data=Path(args.data) if args.data else None,
        database=args.database,
        host=args.host,
        port=args.port,
    )
    try:
        service = StationService(settings)
    except (ConfigurationError, RecordError, OSError, ValueError):
        return 1
    try:
        token, generated = resolve_token(service.config.api.token if service.config is not None else None)
    except ValueError:
        service.close()
        return 2
    open_reads = (service.config.api.open_reads if service.config is not None else True) and is_loopback(
        args.host
    )
    app = create_app(service, Access(token=token, open_reads=open_reads))
    config = uvicorn.Config(
        app,
        host=args.host,
        port=args.port,
        access_log=False,  # request lines carry the login URL's token
        log_config=None,  # uvicorn logs through the station's logging (stderr)
        timeout_graceful_shutdown=5,
        lifespan="on",
    )
    server = uvicorn.Server(config)
    original_startup = server.startup

    async def startup(sockets: object = None) -> None:
        await original_startup(sockets=sockets)  # type: ignore[arg-type]
        port = server.servers[0].sockets[0].getsockname()[1] if server.servers else args.port
        host = f"[{args.host}]" if ":" in args.host else args.host
        base = f"http://{host}:{port}/"
        # The URL with the token goes to stdout once, never through logging.
        if generated:
            print(f"station serve: open {base}?token={token}", flush=True)
        else:
            print(f"station serve: open {base} (token: configured or STATION_API_TOKEN)", flush=True)
        print(f"station serve: API {base}api/v1/docs ; Ctrl-C stops", flush=True)

    server.startup = startup  # type: ignore[method-assign]
    try:
        server.run()
    finally:
        service.close()  # idempotent: after a failed start-up too (port taken ...)
    return 0 if server.started else 1
