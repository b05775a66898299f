"""``station serve``: the station as a service (registered through the ``station.cli`` entry point).

It keeps running until Ctrl-C (or SIGTERM), which shuts down cleanly: a running session is aborted
(the robot stopped through its latched ``stop()``, the open prompt cancelled), recorded as
``interrupted`` (resume it through the API), and the devices are closed.

A service that cannot start says why in one line on stderr: exit 2 for a bad option or token, 1 for
anything else (a port in use, a data directory it cannot write, a station that does not come up).
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import re
import sys
from pathlib import Path

from station.commands import SubParsers
from station.commands.run import add_record_options

log = logging.getLogger(__name__)

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8465
HOSTS_ENV = "STATION_ALLOWED_HOSTS"
_HOST_NAME = re.compile(r"^(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9]([A-Za-z0-9.-]{0,252}))$")


def register(sub: SubParsers) -> None:
    from station.imageio import DEFAULT_MAX_DECODED_BYTES

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
    p.add_argument(
        "--allowed-host",
        action="append",
        default=[],
        metavar="NAME",
        help="also answer requests addressed to this host name (repeatable; also $STATION_ALLOWED_HOSTS, "
        "comma-separated); localhost, 127.0.0.1, [::1] and the bound address always are",
    )
    p.add_argument(
        "--public-read",
        action="store_true",
        help="let anyone who reaches the service read it without the token (sessions, images, reports, the "
        "camera); for a trusted network only",
    )
    p.add_argument(
        "--allow-remote-motion",
        action="store_true",
        help="let clients on other machines (with the token) start and resume sessions and move the arm; "
        "by default only clients on the station itself can, where someone sees the arm (pause, stop and "
        "abort are always open to the token)",
    )
    p.add_argument(
        "--max-decoded-mb",
        type=float,
        default=DEFAULT_MAX_DECODED_BYTES / 2**20,
        metavar="MB",
        help="refuse uploaded images whose header declares a larger decoded size (width x height x channels "
        f"x bytes per sample; MiB, default {DEFAULT_MAX_DECODED_BYTES // 2**20})",
    )
    add_record_options(p)
    p.set_defaults(func=lambda args: serve(p, args))


def _one_line(exc: BaseException) -> str:
    text = " ".join(line.strip() for line in str(exc).splitlines() if line.strip())
    return text or type(exc).__name__


def _fail(message: str, code: int = 1) -> int:
    print(f"station serve: {message}", file=sys.stderr, flush=True)
    return code


def allowed_host_names(given: list[str]) -> list[str]:
    """``--allowed-host`` names and ``$STATION_ALLOWED_HOSTS``'; ValueError naming a bad one."""
    names = [*given, *re.split(r"[,\s]+", os.environ.get(HOSTS_ENV, ""))]
    out = []
    for name in (n.strip() for n in names):
        if not name:
            continue
        if not _HOST_NAME.fullmatch(name):
            raise ValueError(
                f"{name!r} is not a host name (letters, digits, dots and hyphens, or [IPv6]): fix "
                f"--allowed-host or ${HOSTS_ENV}"
            )
        out.append(name)
    return out


def serve(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    import uvicorn

    from api import (
        Access,
        AllowedHosts,
        ListenError,
        ServeLimits,
        ServiceSettings,
        StationService,
        TokenError,
        create_app,
        is_loopback,
        listen,
        resolve_token,
        server_config,
    )
    from station.config import load_config

    if args.manual_prompts and not args.sim:
        parser.error(
            "--manual-prompts needs --sim (a configured station's prompts are answered in the page anyway)"
        )
    if not 0 <= args.port <= 65535:
        parser.error(f"--port must be 0-65535, got {args.port}")
    if not (math.isfinite(args.max_decoded_mb) and 1 <= args.max_decoded_mb <= 65536):
        parser.error(f"--max-decoded-mb must be 1-65536 (MiB), got {args.max_decoded_mb}")
    try:
        names = allowed_host_names(args.allowed_host)
    except ValueError as exc:
        parser.error(str(exc))
    # what can be refused at once comes first: the configuration, the token, the port; then the station
    try:
        config = load_config(Path(args.config)) if args.config else None
        token, generated = resolve_token(config.api.token if config is not None else None)
    except TokenError as exc:
        return _fail(str(exc), 2)
    except Exception as exc:  # noqa: BLE001 - one line, whatever it is
        return _fail(f"cannot start: {_one_line(exc)}")
    public_read = args.public_read or (config is not None and config.api.open_reads)
    if public_read and not is_loopback(args.host):
        log.warning(
            "reads are public (--public-read) and the service is bound to %s, not loopback: anyone who can "
            "reach it sees the station's sessions, images and camera without the token",
            args.host,
        )
    try:
        sock = listen(args.host, args.port)
    except ListenError as exc:
        return _fail(str(exc))
    settings = ServiceSettings(
        sim=args.sim,
        manual_prompts=args.manual_prompts,
        config=Path(args.config) if args.config else None,
        data=Path(args.data) if args.data else None,
        database=args.database,
        host=args.host,
        port=sock.getsockname()[1],
    )
    try:
        service = StationService(settings)
    except Exception as exc:
        sock.close()
        log.debug("station serve could not start", exc_info=exc)
        return _fail(f"cannot start: {_one_line(exc)}")
    limits = ServeLimits(max_decoded_bytes=int(args.max_decoded_mb * 2**20))
    hosts = AllowedHosts.of(names, bound=args.host)
    remote_motion = args.allow_remote_motion or (config is not None and config.api.allow_remote_motion)
    if remote_motion and not is_loopback(args.host):
        log.warning(
            "remote motion is allowed (--allow-remote-motion) and the service is bound to %s: any client "
            "holding the token can start sessions that move the arm, from anywhere that reaches it",
            args.host,
        )
    access = Access(token=token, public_read=public_read, remote_motion=remote_motion)
    app = create_app(service, access, limits=limits, hosts=hosts)
    server = uvicorn.Server(server_config(app, limits, timeout_graceful_shutdown=5))
    original_startup = server.startup

    async def startup(sockets: object = None) -> None:
        await original_startup(sockets=sockets)  # type: ignore[arg-type]
        port = sock.getsockname()[1]
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
        server.run(sockets=[sock])
    except SystemExit:  # uvicorn exits when its start-up fails (it has logged why)
        return _fail("the server did not start (see the log above)")
    finally:
        service.close()  # idempotent: after a failed start-up too
        sock.close()
    return 0 if server.started else _fail("the server did not start (see the log above)")
