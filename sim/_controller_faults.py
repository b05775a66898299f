"""Faults the controller twin can inject, each aimed at the Nth command line it receives.

* ``garble``: the reply comes back with line noise (bit 7 set on some characters; a noise line when
  the reply is empty); the prompt is intact.
* ``drop``: echo only, then nothing: no reply, no prompt.
* ``error``: the command is not run; the controller prints an error text instead.
* ``disconnect``: the pty disappears (cable pulled); it comes back on a new pty after
  ``replug_after_s`` (the twin's stable link path follows it), or when ``replug()`` is called.
* ``slow``: the reply (and prompt) come ``delay_s`` late.
* ``servo``: the motion starts, then at ``fraction`` of its duration the arm stops and the robot server
  prints ``/sbin/robotsrv: <text> (error code 0x...)`` unprompted [the form: inferred].

On the command line: ``KIND@N[:VALUE]`` (``garble@2``, ``slow@1:1.5``, ``error@3:007 Arm power is OFF``,
``disconnect@1:0.5``, ``servo@2:Excessive lag error on axis 1``).
"""

from __future__ import annotations

from enum import StrEnum

from pydantic import BaseModel, ConfigDict, Field


class FaultKind(StrEnum):
    GARBLE = "garble"
    DROP = "drop"
    ERROR = "error"
    DISCONNECT = "disconnect"
    SLOW = "slow"
    SERVO = "servo"


DEFAULT_ERROR_TEXT = "007 Arm power is OFF"
DEFAULT_SERVO_TEXT = "Excessive lag error on axis 1"


class Fault(BaseModel):
    """One fault: what, on which command (1 = the next one), and its parameter."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    kind: FaultKind
    at: int = Field(1, ge=1, description="the Nth command line received (counted from injection)")
    on: str | None = Field(
        None,
        min_length=1,
        description="count only command lines beginning with this text (e.g. 'joint 2'): a fault aimed at"
        " one command whatever polls the host sends before it",
    )
    text: str | None = Field(
        None, description="error, servo: the controller's text (lines split on \\n); None: the default"
    )
    fraction: float = Field(0.5, gt=0, lt=1, description="servo: when, as a fraction of the motion")
    delay_s: float = Field(1.0, ge=0, description="slow: how late the reply comes (real seconds)")
    execute: bool = Field(True, description="garble, drop, slow: whether the command still runs")
    replug_after_s: float | None = Field(None, ge=0, description="disconnect: back after this (real seconds)")


def parse_fault(spec: str) -> Fault:
    """``KIND@N[:VALUE]`` -> :class:`Fault` (VALUE: error text, slow delay, disconnect replug delay)."""
    head, _, value = spec.partition(":")
    kind_text, _, at_text = head.partition("@")
    try:
        kind = FaultKind(kind_text.strip().lower())
    except ValueError:
        choices = ", ".join(k.value for k in FaultKind)
        raise ValueError(f"fault {spec!r}: kind must be one of {choices}") from None
    try:
        at = int(at_text) if at_text else 1
    except ValueError:
        raise ValueError(f"fault {spec!r}: N in KIND@N must be a whole number") from None
    fields: dict[str, object] = {"kind": kind, "at": at}
    if value:
        if kind in (FaultKind.ERROR, FaultKind.SERVO):
            fields["text"] = value.replace("\\n", "\n")
        elif kind is FaultKind.SLOW:
            fields["delay_s"] = float(value)
        elif kind is FaultKind.DISCONNECT:
            fields["replug_after_s"] = float(value)
        else:
            raise ValueError(f"fault {spec!r}: {kind.value} takes no value")
    return Fault.model_validate(fields)


def garble(lines: list[str]) -> list[str]:
    """Line noise: set bit 7 on every third character; an empty reply gets a noise line."""
    if not any(lines):
        return ["\x8f\x93#\xa1!\xfe"]
    return ["".join(chr(ord(c) | 0x80) if i % 3 == 1 else c for i, c in enumerate(line)) for line in lines]


__all__ = ["DEFAULT_ERROR_TEXT", "DEFAULT_SERVO_TEXT", "Fault", "FaultKind", "garble", "parse_fault"]
