"""A local acknowledgement: the proof, asked for by a robot's stop latch, that a person AT the station saw
the arm after a stop, an E-stop or a controller error and let it move again.

After any of those the driver latches (every motion refused) and only ``acknowledge_stop(ack)`` with a
:class:`LocalAcknowledgement` releases it. Such a token is made only by its two factories, each of which
checks where the request comes from:

* :meth:`LocalAcknowledgement.from_terminal`: a person at the station's own terminal (standard input a
  terminal, and not an SSH login): ``station robot --config F acknowledge`` asks them to type ``yes``;
* :meth:`LocalAcknowledgement.from_loopback`: a request whose peer address (the TCP connection's, never
  a header a client writes, such as ``X-Forwarded-For``) is a loopback address: the operator page opened
  on the station itself. A service route calls it with the connection's peer and maps
  :class:`RemoteAcknowledgementError` to 403, so no remote client can release the latch.

Each token is fresh (``MAX_AGE_S``) and single-use: the driver refuses an old or replayed one.
"""

from __future__ import annotations

import ipaddress
import logging
import os
import secrets
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import IO, Literal

__all__ = [
    "ACKNOWLEDGE_HINT",
    "MAX_AGE_S",
    "LocalAcknowledgement",
    "RemoteAcknowledgementError",
]

log = logging.getLogger(__name__)

MAX_AGE_S = 120.0
"""A token older than this (seconds) is refused: acknowledge again."""

ACKNOWLEDGE_HINT = (
    "look at the arm and the cell, then acknowledge the stop at the station: `station robot --port PORT"
    " --config FILE acknowledge` at its own terminal, or the operator page opened on the station itself"
    " (its Robot panel: POST /api/v1/station/robot/acknowledge from the station)"
)
"""What to do about a latched stop (refusals end with it)."""

_SSH_VARIABLES = ("SSH_CONNECTION", "SSH_CLIENT", "SSH_TTY")
_FACTORY = object()


class RemoteAcknowledgementError(PermissionError):
    """A stop acknowledgement asked for from somewhere other than the station itself; nothing released."""

    code = "remote_acknowledgement"


@dataclass(frozen=True)
class LocalAcknowledgement:
    """Who acknowledged (``source``: ``terminal`` or ``loopback``; ``who``: the terminal's name or the
    peer address), when (``at``, epoch seconds) and a single-use ``nonce``. Made only by the factories."""

    source: Literal["terminal", "loopback"]
    who: str
    at: float
    nonce: str
    _key: object = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self._key is not _FACTORY:
            raise TypeError(
                "a LocalAcknowledgement is made only by LocalAcknowledgement.from_terminal() or"
                " .from_loopback(), which check that the request comes from the station itself"
            )

    def fresh(self, now: float | None = None) -> bool:
        """Whether it is at most :data:`MAX_AGE_S` old."""
        age = (time.time() if now is None else now) - self.at
        return -5.0 <= age <= MAX_AGE_S

    @classmethod
    def from_terminal(
        cls,
        stream: IO[str] | None = None,
        *,
        environ: Mapping[str, str] | None = None,
        clock: Callable[[], float] = time.time,
    ) -> LocalAcknowledgement:
        """A person at the station's own terminal: ``stream`` (standard input by default) must be a
        terminal and the process must not run in an SSH login (RemoteAcknowledgementError otherwise)."""
        stream = sys.stdin if stream is None else stream
        env = os.environ if environ is None else environ
        try:
            fd = stream.fileno()
            is_tty = os.isatty(fd)
        except (AttributeError, OSError, ValueError):
            is_tty = False
        if not is_tty:
            raise RemoteAcknowledgementError(
                "a stop is acknowledged by a person at the station's terminal: standard input is not a"
                " terminal (a script or a pipe cannot acknowledge it)"
            )
        remote = [name for name in _SSH_VARIABLES if env.get(name)]
        if remote:
            raise RemoteAcknowledgementError(
                f"this terminal is an SSH login ({remote[0]} is set): acknowledge the stop at the station's"
                " own terminal, where the arm can be seen"
            )
        try:
            who = os.ttyname(fd)
        except OSError:
            who = "terminal"
        return cls("terminal", who, clock(), secrets.token_hex(8), _FACTORY)

    @classmethod
    def from_loopback(
        cls, peer_host: str | None, *, clock: Callable[[], float] = time.time
    ) -> LocalAcknowledgement:
        """A request from the station itself: ``peer_host`` is the connection's peer address (e.g.
        Starlette's ``request.client.host``), which must be a loopback address."""
        try:
            address = ipaddress.ip_address((peer_host or "").strip("[]"))
        except ValueError:
            address = None
        if address is None or not address.is_loopback:
            raise RemoteAcknowledgementError(
                f"a stop cannot be acknowledged from {peer_host or 'an unknown address'}: only from the"
                " station itself (its terminal, or the operator page opened on it at 127.0.0.1), where the"
                " arm can be seen"
            )
        return cls("loopback", str(address), clock(), secrets.token_hex(8), _FACTORY)
