"""Operator prompts: a device or plan asks a person to do something and waits for the answer.

An operator step pauses the work with a message until someone answers it (Opentrons-style); the
question is a value held by a :class:`PromptBroker`, and every front end (the API and its page, a
terminal, a simulated operator) is a client of the same broker. Nothing here reads stdin or does I/O.

* ``ask(...)`` opens a prompt and returns a :class:`PromptHandle`; only one prompt is open at a time
  (a second ``ask`` raises :class:`PromptBusyError`).
* ``handle.wait(timeout=None)`` blocks the calling thread only, until the prompt is answered; it waits
  forever unless a timeout is given, and on a timeout the prompt stays open (``handle.withdraw()``
  closes it).
* Any other thread answers by id: ``confirm(prompt_id, readings=None)`` or ``cancel(prompt_id)``. An
  answer to a prompt that is no longer open (a stale page) raises :class:`UnknownPromptError`.
* ``subscribe(listener)`` reports every change as a :class:`PromptEvent`, in order. Listeners run on a
  thread that made a change and must not block (an asyncio server hands events to its loop with
  ``call_soon_threadsafe``); they may answer prompts themselves. ``revision`` increases at every
  change: push "refetch" and let clients read ``current()``.

Clock and id generator are injected, so tests are deterministic.
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
import time
import uuid
from collections import deque
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from enum import StrEnum

log = logging.getLogger(__name__)


class PromptError(RuntimeError):
    """Base class of prompt failures."""


class PromptBusyError(PromptError):
    """Another prompt is open; it must be answered (or cancelled) before a new one is asked."""

    def __init__(self, open_prompt: Prompt) -> None:
        super().__init__(
            f"an operator prompt is already open ({open_prompt.id}: {open_prompt.message!r}); "
            "answer or cancel it first"
        )
        self.open_prompt = open_prompt


class UnknownPromptError(PromptError, LookupError):
    """No open prompt has this id (it was answered, withdrawn, or never existed)."""


class InvalidAnswerError(PromptError, ValueError):
    """The readings given with a confirmation are not acceptable; the prompt stays open."""


class PromptWaitTimeoutError(PromptError, TimeoutError):
    """``wait`` gave up before the prompt was answered; the prompt is still open."""


class Outcome(StrEnum):
    """How a prompt was closed."""

    CONFIRMED = "confirmed"
    CANCELLED = "cancelled"
    WITHDRAWN = "withdrawn"  # closed by the asker (e.g. it stopped waiting), not by the operator


@dataclass(frozen=True)
class PromptField:
    """A value the operator may report when confirming (e.g. a micrometer reading).

    ``requested`` is the value asked for, shown as the default; ``unit`` is a display unit.
    """

    name: str
    label: str
    unit: str = ""
    requested: float | None = None


@dataclass(frozen=True)
class Prompt:
    """An open question to the operator."""

    id: str
    kind: str
    message: str
    fields: tuple[PromptField, ...] = ()
    source: str = ""
    created_s: float = 0.0
    details: Mapping[str, str | float] = field(default_factory=dict)


@dataclass(frozen=True)
class PromptAnswer:
    """How a prompt was closed: outcome, readings given with a confirmation, when and by whom."""

    prompt: Prompt
    outcome: Outcome
    readings: Mapping[str, float] = field(default_factory=dict)
    answered_s: float = 0.0
    by: str = ""
    reason: str = ""

    @property
    def confirmed(self) -> bool:
        return self.outcome is Outcome.CONFIRMED


@dataclass(frozen=True)
class PromptEvent:
    """A change: ``opened`` (``answer`` is None) or ``closed`` (``answer`` says how)."""

    kind: str
    prompt: Prompt
    revision: int
    answer: PromptAnswer | None = None


Validator = Callable[[Mapping[str, float]], None]
"""Checks confirmed readings; raises ValueError with a message for the operator to reject them."""

Listener = Callable[[PromptEvent], None]


class _Record:
    """A prompt and, once closed, its answer (shared by the broker and the prompt's handle)."""

    __slots__ = ("announced", "answer", "prompt", "validate")

    def __init__(self, prompt: Prompt, validate: Validator | None) -> None:
        self.prompt = prompt
        self.validate = validate
        self.answer: PromptAnswer | None = None
        self.announced = False  # every listener has seen it open: now it is shown to pollers


class PromptHandle:
    """The asker's side of one prompt."""

    def __init__(self, broker: PromptBroker, record: _Record) -> None:
        self._broker = broker
        self._record = record

    @property
    def prompt(self) -> Prompt:
        return self._record.prompt

    @property
    def id(self) -> str:
        return self._record.prompt.id

    def done(self) -> bool:
        """Whether the prompt has been answered or withdrawn."""
        return self._record.answer is not None

    def wait(self, timeout: float | None = None) -> PromptAnswer:
        """Block this thread until the prompt is closed and return the answer.

        Without ``timeout`` it waits as long as it takes. After ``timeout`` seconds without an answer
        it raises :class:`PromptWaitTimeoutError` and the prompt stays open: wait again, or ``withdraw()``.
        """
        return self._broker._wait(self._record, timeout)

    def withdraw(self, reason: str = "") -> PromptAnswer:
        """Close the prompt from the asker's side; if it was already answered, return that answer."""
        return self._broker._withdraw(self._record, reason)


class PromptBroker:
    """Holds the one open operator prompt and passes answers back to the thread that asked.

    Thread-safe; no method blocks except ``PromptHandle.wait`` and ``wait_for_prompt``.
    """

    def __init__(
        self,
        *,
        clock: Callable[[], float] = time.time,
        new_id: Callable[[], str] = lambda: uuid.uuid4().hex,
    ) -> None:
        self._clock = clock
        self._new_id = new_id
        self._cond = threading.Condition(threading.Lock())
        self._open: _Record | None = None
        self._listeners: list[Listener] = []
        self._revision = 0
        self._pending: deque[PromptEvent] = deque()
        self._dispatching = False
        self._context = threading.local()

    @contextlib.contextmanager
    def context(self, **details: str | float) -> Iterator[None]:
        """Add ``details`` to every prompt this thread asks inside the block (the asker's own details win).

        Who asks (a device) does not know why: the session runner says which step of how many it is in
        (``position``, ``positions``) and what the move is for (``move``: ``overshoot`` or ``position``)."""
        outer: dict[str, str | float] = getattr(self._context, "details", {})
        self._context.details = {**outer, **details}
        try:
            yield
        finally:
            self._context.details = outer

    # ------------------------------------------------------------------ asking

    def ask(
        self,
        message: str,
        *,
        kind: str = "operator",
        fields: Sequence[PromptField] = (),
        source: str = "",
        details: Mapping[str, str | float] | None = None,
        validate: Validator | None = None,
    ) -> PromptHandle:
        """Open a prompt showing ``message``; raise PromptBusyError if one is already open.

        ``fields`` are readings the operator may report on confirmation; ``validate`` checks them
        (raising ValueError keeps the prompt open and tells the operator why).
        """
        if not message.strip():
            raise ValueError("prompt message is empty; say what the operator should do")
        names = [f.name for f in fields]
        if len(set(names)) != len(names):
            raise ValueError(f"prompt fields must have distinct names, got {names}")
        with self._cond:
            if self._open is not None:
                raise PromptBusyError(self._open.prompt)
            prompt = Prompt(
                id=self._new_id(),
                kind=kind,
                message=message,
                fields=tuple(fields),
                source=source,
                created_s=self._clock(),
                details={**getattr(self._context, "details", {}), **(details or {})},
            )
            record = _Record(prompt, validate)
            self._open = record
            self._changed("opened", prompt, None)
        log.info("prompt %s opened (%s): %s", prompt.id, kind, message)
        self._dispatch()
        return PromptHandle(self, record)

    # ------------------------------------------------------------------ answering

    def current(self, *, pending: bool = False) -> Prompt | None:
        """The open prompt, or None.

        A prompt shows here once every listener has seen it open (a front end that finds it can rely on
        what the listeners did, e.g. the session's state saying it waits for the operator);
        ``pending=True`` also gives one whose opening is still being delivered (to withdraw it).
        """
        with self._cond:
            record = self._open
            return record.prompt if record is not None and (pending or record.announced) else None

    @property
    def revision(self) -> int:
        """Increases by one at every change (opened or closed)."""
        with self._cond:
            return self._revision

    def wait_for_prompt(self, timeout: float | None = None) -> Prompt | None:
        """Block this thread until a prompt is open and return it (None after ``timeout`` s)."""
        with self._cond:
            self._cond.wait_for(lambda: self._open is not None and self._open.announced, timeout)
            return self._open.prompt if self._open is not None and self._open.announced else None

    def confirm(
        self, prompt_id: str, readings: Mapping[str, float] | None = None, *, by: str = ""
    ) -> PromptAnswer:
        """Confirm the open prompt, optionally with the readings actually set.

        Raises UnknownPromptError if ``prompt_id`` is not the open prompt, InvalidAnswerError if the
        readings name unknown fields, are not finite numbers, or fail the prompt's validator (the
        prompt then stays open).
        """
        with self._cond:
            record = self._require_open(prompt_id)
            values = self._check_readings(record, readings or {})
            answer = PromptAnswer(
                prompt=record.prompt,
                outcome=Outcome.CONFIRMED,
                readings=values,
                answered_s=self._clock(),
                by=by,
            )
            self._close(record, answer)
        log.info(
            "prompt %s confirmed%s%s", prompt_id, f" by {by}" if by else "", f": {values}" if values else ""
        )
        self._dispatch()
        return answer

    def cancel(self, prompt_id: str, *, reason: str = "", by: str = "") -> PromptAnswer:
        """Cancel the open prompt (the operator declines); UnknownPromptError if it is not open."""
        with self._cond:
            record = self._require_open(prompt_id)
            answer = PromptAnswer(
                prompt=record.prompt,
                outcome=Outcome.CANCELLED,
                answered_s=self._clock(),
                by=by,
                reason=reason,
            )
            self._close(record, answer)
        log.info(
            "prompt %s cancelled%s%s", prompt_id, f" by {by}" if by else "", f": {reason}" if reason else ""
        )
        self._dispatch()
        return answer

    # ------------------------------------------------------------------ listeners

    def subscribe(self, listener: Listener) -> Callable[[], None]:
        """Call ``listener(event)`` at every change; return a function that unsubscribes it."""
        with self._cond:
            self._listeners.append(listener)

        def unsubscribe() -> None:
            with self._cond:
                if listener in self._listeners:
                    self._listeners.remove(listener)

        return unsubscribe

    # ------------------------------------------------------------------ internals (handle side)

    def _wait(self, record: _Record, timeout: float | None) -> PromptAnswer:
        if timeout is not None and (math.isnan(timeout) or timeout < 0):
            raise ValueError(f"timeout must be >= 0 seconds or None, got {timeout!r}")
        with self._cond:
            self._cond.wait_for(lambda: record.answer is not None, timeout)
            if record.answer is None:
                raise PromptWaitTimeoutError(
                    f"no answer to prompt {record.prompt.id} within {timeout} s; it is still open"
                )
            return record.answer

    def _withdraw(self, record: _Record, reason: str) -> PromptAnswer:
        with self._cond:
            if record.answer is not None:
                return record.answer
            answer = PromptAnswer(
                prompt=record.prompt, outcome=Outcome.WITHDRAWN, answered_s=self._clock(), reason=reason
            )
            self._close(record, answer)
        log.info("prompt %s withdrawn: %s", record.prompt.id, reason or "no reason given")
        self._dispatch()
        return answer

    # ------------------------------------------------------------------ internals (lock held)

    def _require_open(self, prompt_id: str) -> _Record:
        record = self._open
        if record is None or record.prompt.id != prompt_id:
            now = f"the open prompt is {record.prompt.id}" if record else "no prompt is open"
            raise UnknownPromptError(f"prompt {prompt_id} is not open ({now}); refetch and answer that")
        return record

    @staticmethod
    def _check_readings(record: _Record, readings: Mapping[str, float]) -> dict[str, float]:
        known = {f.name for f in record.prompt.fields}
        unknown = sorted(set(readings) - known)
        if unknown:
            allowed = ", ".join(sorted(known)) or "none"
            raise InvalidAnswerError(f"unknown reading(s) {unknown}; this prompt takes: {allowed}")
        values: dict[str, float] = {}
        for name, value in readings.items():
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise InvalidAnswerError(f"reading {name!r} must be a finite number, got {value!r}")
            values[name] = float(value)
        if values and record.validate is not None:
            try:
                record.validate(values)
            except ValueError as exc:
                raise InvalidAnswerError(str(exc)) from exc
        return values

    def _close(self, record: _Record, answer: PromptAnswer) -> None:
        record.answer = answer
        if self._open is record:
            self._open = None
        self._changed("closed", record.prompt, answer)

    def _changed(self, kind: str, prompt: Prompt, answer: PromptAnswer | None) -> None:
        self._revision += 1
        self._pending.append(PromptEvent(kind=kind, prompt=prompt, revision=self._revision, answer=answer))
        self._cond.notify_all()

    # ------------------------------------------------------------------ internals (lock not held)

    def _dispatch(self) -> None:
        """Deliver queued events in revision order, outside the lock.

        One thread delivers at a time; a change made meanwhile (also from inside a listener) is queued
        and delivered by that same loop, so listeners see events in order and may call the broker.
        """
        with self._cond:
            if self._dispatching:
                return
            self._dispatching = True
        try:
            while True:
                with self._cond:
                    if not self._pending:
                        self._dispatching = False
                        return
                    event = self._pending.popleft()
                    listeners = list(self._listeners)
                for listener in listeners:
                    try:
                        listener(event)
                    except Exception:  # a faulty front end must not break the asker or the others
                        log.exception("prompt listener %r failed on %s event", listener, event.kind)
                if event.kind == "opened":
                    with self._cond:
                        record = self._open
                        if record is not None and record.prompt.id == event.prompt.id:
                            record.announced = True
                            self._cond.notify_all()
        except BaseException:
            with self._cond:
                self._dispatching = False
            raise


__all__ = [
    "InvalidAnswerError",
    "Outcome",
    "Prompt",
    "PromptAnswer",
    "PromptBroker",
    "PromptBusyError",
    "PromptError",
    "PromptEvent",
    "PromptField",
    "PromptHandle",
    "PromptWaitTimeoutError",
    "UnknownPromptError",
    "Validator",
]
