"""The store pipeline: a step's captures stored (lossless, fsynced), measured from the stored file and
recorded in a thread of their own, in order, while the next step's motions run (the arm never waits for
the disk); and what a plan's analysis gets back from the record.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from station import __version__
from station.batch import measure_file
from station.devices import Frame
from station.plans import Step
from station.plans._ruler import capture_params, measured
from station.record import Record
from station.runner._journal import Journal
from station.runner._states import EARLY_FAILURE_CAPTURES, SessionError
from station.vision import MeasureParams

log = logging.getLogger("station.runner")


@dataclass(frozen=True)
class Grabbed:
    """One capture action's frames, with the meta recorded with each (where the arm was, z ...) and the
    frame index of the first."""

    frames: list[Frame]
    meta: dict[str, Any]
    first_frame: int


@dataclass
class StepRun:
    """One attempt of one step: what it grabbed (stored even when the step fails), the data its actions
    added, where a ``MoveOffset``'s offsets start, and the next frame's index."""

    step: Step
    next_frame: int
    started_s: float = 0.0  # time.monotonic() when the step began (its duration feeds the ETA)
    grabbed: list[Grabbed] = field(default_factory=list)
    data: dict[str, Any] = field(default_factory=dict)
    offset_base: tuple[float, ...] | None = None


@dataclass
class StorePipeline:
    """Stores and measures what each step grabbed, then finishes the step in the record.

    ``on_step_done(step, seconds)`` is called once a step of the session is ``done``; it returns the
    session's progress for the ``step_finished`` event.
    """

    record: Record
    journal: Journal
    measure_params: MeasureParams
    scale_calibration: dict[str, Any] | None
    on_step_done: Callable[[Step, float], dict[str, Any]]
    captures: int = 0
    measured_ok: int = 0
    measured_tried: int = 0
    last_error: str | None = None
    _pool: ThreadPoolExecutor | None = None
    _futures: list[Future[None]] = field(default_factory=list)

    def open(self) -> None:
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="runner-store")

    def close(self, error: str | None) -> None:
        """Store what is still queued (nothing captured is lost), then end the store thread."""
        pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=True)
        for f in self._futures:
            exc = f.exception()
            if exc is not None and str(exc) != error:
                log.error("storing a capture failed: %s", exc)

    def submit(self, sid: str, run: StepRun, failed: str | None = None) -> None:
        """Queue the step's storing; at most one step stored behind the arm (memory stays flat, errors
        surface within a step)."""

        def task() -> None:
            self._store_step(sid, run, failed)

        if self._pool is None:
            task()
            return
        self._futures = [f for f in self._futures if not f.done() or f.exception() is not None]
        self._futures.append(self._pool.submit(task))
        while sum(not f.done() for f in self._futures) > 1:
            next(f for f in self._futures if not f.done()).exception()  # waits for it

    def check(self) -> None:
        """Raise the first error of the store thread (disk full, record lost ...) in the runner thread."""
        for f in self._futures:
            if f.done() and f.exception() is not None:
                exc = f.exception()
                self._futures = [g for g in self._futures if g is not f]
                assert exc is not None
                raise exc

    def drain(self) -> None:
        """Wait until everything grabbed is stored; errors are left for ``check``."""
        for f in list(self._futures):
            f.exception()

    def _store_step(self, sid: str, run: StepRun, failed: str | None) -> None:
        """In the store thread: store and measure the step's frames, then finish the step."""
        step, data = run.step, run.data
        try:
            ids = [cid for g in run.grabbed for cid in self._store(sid, step, g)]
        except BaseException as exc:
            self.record.finish_step(sid, step.index, data={**data, "error": str(exc)}, state="failed")
            raise
        if ids:
            data = {**data, "captures": ids}
        if failed is not None:
            self.record.finish_step(sid, step.index, data={**data, "error": failed}, state="failed")
            return
        self.record.finish_step(sid, step.index, data=data)
        progress = self.on_step_done(step, time.monotonic() - run.started_s)
        self.journal.emit("step_finished", {"index": step.index, "name": step.name, "progress": progress})
        if self.measured_tried >= EARLY_FAILURE_CAPTURES and self.measured_ok == 0:
            raise SessionError(
                f"none of the first {self.measured_tried} captures could be measured"
                f" (last: {self.last_error}); "
                "check that the artifact (the crossing, or the ruler) is in view and in focus, the lighting, "
                "and the measurement parameters, then start again"
            )

    def _store(self, sid: str, step: Step, grabbed: Grabbed) -> list[int]:
        """Store each frame (lossless, fsynced), then measure it from the stored file and record that."""
        ids = []
        software = f"station {__version__}"
        meta = grabbed.meta
        shape = grabbed.frames[0].image.shape if grabbed.frames else (0, 0)
        params = capture_params(meta, self.measure_params, shape)  # a frame of a ruler: measure_ruler's
        params_doc = params.model_dump(mode="json")
        for fi, frame in enumerate(grabbed.frames):
            cap = self.record.save_capture(
                sid,
                step.index,
                grabbed.first_frame + fi,
                frame.image,
                timestamp_s=frame.timestamp_s,
                meta={**meta, "frame_id": frame.frame_id},
                z_mm=meta.get("z_mm"),
            )
            self.captures += 1
            self.journal.emit(
                "image_captured", {"capture_id": cap.id, "path": cap.path, "step": step.index, "frame": fi}
            )
            ids.append(cap.id)
            if not measured(meta):
                continue  # not a groove artifact (a calibration target's view): stored, its plan reads it
            result = measure_file(Path(self.record.data_dir) / cap.path, params).to_json()
            result["file"] = cap.path
            if self.scale_calibration is not None and result.get("ok") and params is self.measure_params:
                result.setdefault("diagnostics", {})["scale_calibration"] = self.scale_calibration
            self.record.add_measurement(sid, cap.id, result, params=params_doc, software=software)
            ok = bool(result.get("ok"))
            self.measured_ok += ok
            self.measured_tried += 1
            if not ok:
                self.last_error = result.get("error")
            self.journal.emit(
                "measurement",
                {
                    "capture_id": cap.id,
                    "ok": ok,
                    "center_px": result.get("center_px"),
                    "center_mm": result.get("center_mm"),
                    "z_mm": meta.get("z_mm"),
                    "error": result.get("error"),
                    "code": result.get("code"),
                },
            )
        return ids
