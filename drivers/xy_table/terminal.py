"""Answer operator prompts from a terminal: a thin client of ``station.prompts.PromptBroker``.

The terminal shows the open prompt and reads one line: Enter (or ``y``) confirms as asked, numbers
confirm with the readings actually set (in the order of the prompt's fields, or ``x_in=0.0102``),
``c`` cancels. It answers through the broker like any other front end, so a prompt answered elsewhere
(the API's page) is simply reported as gone.
"""

from __future__ import annotations

import logging
import sys
import threading
from typing import TextIO

from station.prompts import (
    InvalidAnswerError,
    Prompt,
    PromptAnswer,
    PromptBroker,
    UnknownPromptError,
)

log = logging.getLogger(__name__)

CONFIRM_WORDS = frozenset({"", "y", "yes", "ok", "done"})
CANCEL_WORDS = frozenset({"c", "cancel", "n", "no", "q", "quit"})


def parse_readings(text: str, prompt: Prompt) -> dict[str, float]:
    """Readings typed by the operator: ``0.0102 0.0000`` (fields in order) or ``x_in=0.0102``.

    Raises ValueError with a message for the operator.
    """
    names = [f.name for f in prompt.fields]
    if not names:
        raise ValueError("this prompt takes no readings: press Enter to confirm or c to cancel")
    readings: dict[str, float] = {}
    tokens = text.replace(",", " ").split()
    for i, token in enumerate(tokens):
        name, sep, value = token.partition("=")
        if not sep:
            if i >= len(names):
                raise ValueError(f"too many readings: this prompt takes {len(names)} ({', '.join(names)})")
            name, value = names[i], token
        if name not in names:
            raise ValueError(f"unknown reading {name!r}; this prompt takes {', '.join(names)}")
        try:
            readings[name] = float(value)
        except ValueError:
            raise ValueError(f"{name}: {value!r} is not a number") from None
    return readings


def describe(prompt: Prompt) -> str:
    """The text shown for ``prompt``: message, fields with their requested values, and the keys."""
    origin = prompt.source or prompt.kind
    header = prompt.message if prompt.message.startswith(origin) else f"[{origin}] {prompt.message}"
    lines = ["", header]
    for f in prompt.fields:
        requested = "" if f.requested is None else f" (asked: {f.requested:.4f} {f.unit})".rstrip()
        lines.append(f"  {f.name}: {f.label}{requested}")
    keys = "Enter = confirm as asked"
    if prompt.fields:
        keys += f", or type the readings set ({' '.join(f.name for f in prompt.fields)})"
    lines.append(f"  {keys}; c = cancel")
    return "\n".join(lines) + "\n> "


class TerminalPromptClient:
    """Shows each open prompt on ``stdout`` and answers it from lines read on ``stdin``."""

    def __init__(
        self,
        broker: PromptBroker,
        *,
        stdin: TextIO | None = None,
        stdout: TextIO | None = None,
        name: str = "terminal",
    ) -> None:
        self._broker = broker
        self._in = stdin if stdin is not None else sys.stdin
        self._out = stdout if stdout is not None else sys.stdout
        self._name = name

    def answer_one(self, timeout: float | None = None) -> PromptAnswer | None:
        """Wait for a prompt, show it, and answer it from the terminal.

        Returns the answer, or None when no prompt came within ``timeout`` or the prompt was answered
        elsewhere first. Raises EOFError when the input ends (the prompt is left open for others).
        """
        prompt = self._broker.wait_for_prompt(timeout)
        if prompt is None:
            return None
        self._write(describe(prompt))
        while True:
            line = self._in.readline()
            if not line:
                raise EOFError("terminal input ended; the prompt stays open for another front end")
            text = line.strip()
            try:
                if text.lower() in CONFIRM_WORDS:
                    return self._broker.confirm(prompt.id, by=self._name)
                if text.lower() in CANCEL_WORDS:
                    return self._broker.cancel(prompt.id, reason="cancelled at the terminal", by=self._name)
                return self._broker.confirm(prompt.id, parse_readings(text, prompt), by=self._name)
            except UnknownPromptError:
                self._write("This prompt was already answered elsewhere.\n")
                return None
            except (InvalidAnswerError, ValueError) as exc:
                self._write(f"Not accepted: {exc}\n> ")

    def serve(self, stop: threading.Event, *, poll_s: float = 0.2) -> None:
        """Answer prompts until ``stop`` is set or the input ends."""
        while not stop.is_set():
            try:
                self.answer_one(timeout=poll_s)
            except EOFError:
                log.info("terminal input ended; no longer answering prompts")
                return

    def _write(self, text: str) -> None:
        self._out.write(text)
        self._out.flush()
