"""The simulated operator: answers the station's table prompts by turning the simulated micrometers and
by putting on the table what a session asks for.

It watches a ``station.prompts.PromptBroker`` from its own thread. A prompt that asks for micrometer
readings (fields in inches, ``x_in`` / ``y_in``) is answered after ``delay_s``: the operator turns the
micrometers of the simulated world to the readings asked for (the world's table then moves, with its
backlash and resolution) and confirms with the reading it was asked for, as a person reading the
thimble would. A prompt to put something on the X-Y table (``station.table_content``: kind
``table_content``, ``details["content"]``) is answered by putting that on the world's table
(``World.place_on_table``), then confirming. Other prompts are left for someone else. ``cancel_next``
makes it decline once (tests).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

from sim.world import INCH_MM, TABLE_CONTENTS, TableContent, World
from station.prompts import Prompt, PromptBroker, PromptError, PromptEvent
from station.table_content import PROMPT_KIND as TABLE_CONTENT_KIND

log = logging.getLogger(__name__)

X_FIELD = "x_in"
Y_FIELD = "y_in"


def table_content_asked(prompt: Prompt) -> TableContent | None:
    """What a prompt asks to put on the X-Y table (None: it asks nothing of the kind)."""
    content = prompt.details.get("content") if prompt.kind == TABLE_CONTENT_KIND else None
    return next((c for c in TABLE_CONTENTS if c == content), None)


class SimOperator:
    """Answers micrometer prompts on ``broker`` by moving ``world``'s table, and what-to-put-on-the-table
    prompts by putting it there.

    Parameters
    ----------
    origin_in
        Micrometer readings (in) at the world's table position (0, 0) mm.
    delay_s
        How long the operator takes to turn the micrometers.
    """

    def __init__(
        self,
        broker: PromptBroker,
        world: World,
        *,
        origin_in: tuple[float, float] = (0.0, 0.0),
        delay_s: float = 0.0,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self._broker = broker
        self._world = world
        self._origin_in = origin_in
        self._delay_s = delay_s
        self._sleep = sleep
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._cancel_next = False
        self.answered = 0

    def cancel_next(self) -> None:
        """Decline the next prompt it would answer (as an operator who cannot reach the table would)."""
        self._cancel_next = True

    def start(self) -> SimOperator:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="sim-operator", daemon=True)
            self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None

    def __enter__(self) -> SimOperator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _run(self) -> None:
        handled: set[str] = set()
        while not self._stop.is_set():
            prompt = self._broker.wait_for_prompt(timeout=0.05)
            if prompt is None or prompt.id in handled:
                if prompt is not None:
                    self._stop.wait(0.01)
                continue
            handled.add(prompt.id)
            names = {f.name for f in prompt.fields}
            if not {X_FIELD, Y_FIELD} <= names and table_content_asked(prompt) is None:
                log.debug("sim operator leaves prompt %s (%s) to someone else", prompt.id, prompt.kind)
                continue
            self._answer(prompt)

    def _answer(self, prompt: Prompt) -> None:
        if self._delay_s:
            self._sleep(self._delay_s)
        try:
            if self._cancel_next:
                self._cancel_next = False
                self._broker.cancel(prompt.id, reason="simulated operator declined", by="sim-operator")
                return
            content = table_content_asked(prompt)
            if content is not None:
                self._world.place_on_table(content)
                self._broker.confirm(prompt.id, by="sim-operator")
                self.answered += 1
                return
            asked = {f.name: f.requested for f in prompt.fields}
            x_in, y_in = float(asked[X_FIELD] or 0.0), float(asked[Y_FIELD] or 0.0)
            self._world.set_table_readings(
                (x_in - self._origin_in[0]) * INCH_MM, (y_in - self._origin_in[1]) * INCH_MM
            )
            self._broker.confirm(prompt.id, {X_FIELD: x_in, Y_FIELD: y_in}, by="sim-operator")
            self.answered += 1
        except PromptError as exc:  # the prompt was withdrawn meanwhile: nothing to answer
            log.info("sim operator: prompt %s closed before the answer: %s", prompt.id, exc)


class MicrometerFollower:
    """With a person answering the table prompts (the service's page, ``--manual-prompts``), the simulated
    world's micrometers follow what they confirm: the readings given, else those asked for, so that the
    artifact really moves. Readings a prompt's validator refused never reach the world. What they confirm
    to have put on the table lies there.

    A broker's listeners run after the asker was woken, so ``sync`` (the sim camera's ``before_grab``)
    waits until every prompt change so far has been applied: the camera never sees the old position.
    """

    def __init__(self, broker: PromptBroker, world: World, *, origin_in: tuple[float, float] = (0.0, 0.0)):
        self._broker = broker
        self._world = world
        self._origin_in = origin_in
        self._cond = threading.Condition()
        self._seen = broker.revision
        self.followed = 0
        self._unsubscribe = broker.subscribe(self._on_event)

    def _on_event(self, event: PromptEvent) -> None:
        try:
            answer = event.answer
            names = {f.name for f in event.prompt.fields}
            content = table_content_asked(event.prompt)
            if event.kind == "closed" and answer is not None and answer.confirmed and content is not None:
                self._world.place_on_table(content)
            elif (
                event.kind == "closed"
                and answer is not None
                and answer.confirmed
                and {X_FIELD, Y_FIELD} <= names
            ):
                asked = {f.name: f.requested for f in event.prompt.fields}
                x_in = float(answer.readings.get(X_FIELD, asked[X_FIELD] or 0.0))
                y_in = float(answer.readings.get(Y_FIELD, asked[Y_FIELD] or 0.0))
                self._world.set_table_readings(
                    (x_in - self._origin_in[0]) * INCH_MM, (y_in - self._origin_in[1]) * INCH_MM
                )
                self.followed += 1
        finally:
            with self._cond:
                self._seen = max(self._seen, event.revision)
                self._cond.notify_all()

    def sync(self, timeout_s: float = 2.0) -> None:
        """Wait (at most ``timeout_s``) until every prompt change so far has reached the world."""
        with self._cond:
            self._cond.wait_for(lambda: self._seen >= self._broker.revision, timeout_s)

    def close(self) -> None:
        self._unsubscribe()


def start_sim_operator(
    *, broker: PromptBroker, world: World | None = None, delay_s: float = 0.0
) -> SimOperator:
    """Device factory (``operator.sim``): a simulated operator answering ``broker``'s table prompts."""
    return SimOperator(broker, world or World(), delay_s=delay_s).start()
