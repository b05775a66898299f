"""Scripted sessions: one function that builds the station, runs a plan and returns its outcome.

The CLI's ``station run`` and the example scripts use exactly this; the service's worker
(``station.worker``) starts its sessions with the same rule (``SessionStart``)::

    from station.session import run_session
    outcome = run_session("repeatability", sim=True, params={"cycles": 10})
    print(outcome.state, outcome.results["rp_mm"])
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from station import scale_calibration as scal
from station.compute import ComputeSpec, MeasureBackend, open_backend
from station.config import (
    ConfigurationError,
    StationConfig,
    StationDevices,
    build,
    load_config,
    open_sim_station,
)
from station.config import open_station as build_station
from station.kinds import KIND_NAMES, get_kind, get_plan
from station.plans import Plan, PlanError, parse_params
from station.record import EventRow, Record, SessionRow
from station.resources import SessionOutcome
from station.runner import SessionError, SessionRunner
from station.vision import MeasureParams, field_names

log = logging.getLogger(__name__)

DEFAULT_DATA_DIR = "station-data"
DATA_ENV = "STATION_DATA"


def data_dir_for(data: str | Path | None, config: StationConfig | None = None) -> Path:
    """``--data``, else the configuration's ``data_dir``, else ``$STATION_DATA``, else ``./station-data``."""
    if data is not None:
        return Path(data)
    if config is not None and config.data_dir is not None:
        return config.data_dir
    return Path(os.environ.get(DATA_ENV) or DEFAULT_DATA_DIR)


def open_record(
    data: str | Path | None = None,
    database: str | None = None,
    config: StationConfig | None = None,
    *,
    read_only: bool = False,
) -> Record:
    """The record of ``--data`` / ``--database`` (or the configuration's); ``read_only`` for commands
    that only read it (nothing created, migrated or written)."""
    url = database or (config.database if config is not None else None)
    return Record(data_dir_for(data, config), url, read_only=read_only)


def measure_params_for(
    kind: str,
    base: Mapping[str, Any] | None,
    assignments: Mapping[str, Any],
    calibration: scal.ScaleCalibration | None,
    source: str | Path | None = None,
) -> tuple[MeasureParams, dict[str, Any] | None]:
    """The session's measurement parameters: the kind's defaults (paper for a sweep), then the
    configuration's or the source session's, then ``--set``; the scale calibration's groove width unless
    ``--set`` sets one."""
    return _measure_params(get_kind(kind).measure_defaults, base, assignments, calibration, source)


def _measure_params(
    defaults: Mapping[str, Any],
    base: Mapping[str, Any] | None,
    assignments: Mapping[str, Any],
    calibration: scal.ScaleCalibration | None,
    source: str | Path | None,
) -> tuple[MeasureParams, dict[str, Any] | None]:
    try:
        given = field_names(assignments)
        values = {**defaults, **(base or {}), **scal.width_unless_set(calibration, given)}
        params = MeasureParams.model_validate({**values, **given})
    except ValueError as exc:
        raise PlanError(f"measurement parameters: {exc}") from exc
    return params, calibration.record(source) if calibration is not None else None


def station_measure_params(
    record: Record, cfg: StationConfig | None
) -> tuple[MeasureParams, dict[str, Any] | None]:
    """The station's own measurement parameters (a frame measured outside a session: the operator
    page's overlay): the configuration's, with the station's scale calibration's groove width."""
    calibration, source = _calibration(record, cfg, station_file=True)
    return _measure_params({}, dict(cfg.measure) if cfg is not None else {}, {}, calibration, source)


@contextlib.contextmanager
def terminal_prompts(devices: StationDevices) -> Iterator[None]:
    """Answer the station's operator prompts (the manual table's, what to put on the table) from this
    terminal, in a thread, while the block runs: when the table's prompts are the terminal's, or the
    station has no table (nobody else would answer what to put on it)."""
    table = devices.config.table
    if table is not None and table.prompts != "terminal":
        yield
        return
    client = build("prompt_client", "terminal", broker=devices.broker)
    done = threading.Event()

    def loop() -> None:
        while not done.is_set():
            try:
                client.answer_one(timeout=0.5)
            except EOFError:
                log.warning("terminal input ended: answer the table's prompts through the API")
                return

    thread = threading.Thread(target=loop, name="terminal-prompts", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()


@dataclass(frozen=True)
class SessionStart:
    """What starts a session, new or resumed, wherever it runs (``station run``, the service's worker):
    its plan and validated parameters, its measurement parameters and scale calibration record, and the
    session it resumes (``None`` for a new one)."""

    plan: Plan
    params: BaseModel
    measure: MeasureParams
    scale_calibration: dict[str, Any] | None
    previous: SessionRow | None = None

    @classmethod
    def new(
        cls,
        record: Record,
        kind: str,
        params: Mapping[str, Any],
        cfg: StationConfig | None,
        assignments: Mapping[str, Any] | None = None,
        *,
        check: Callable[[Plan], None] | None = None,
    ) -> SessionStart:
        """A new session of ``kind``: its parameters checked (PlanError naming the field), then
        ``check(plan)`` (whether this station can run it), then the measurement parameters and scale
        calibration as ``session_measure_params`` makes them."""
        plan = get_plan(kind)
        plan_params = parse_params(plan, dict(params))
        if check is not None:
            check(plan)
        measure, cal_doc = session_measure_params(record, kind, dict(params), cfg, assignments)
        return cls(plan, plan_params, measure, cal_doc)

    @classmethod
    def resume(cls, record: Record, session_id: str) -> SessionStart:
        """Session ``session_id`` continued with its own parameters (SessionError for a succeeded one)."""
        previous = record.get_session(session_id)
        if previous.state == "succeeded":
            raise SessionError(f"session {previous.id} succeeded; there is nothing to resume")
        plan = get_plan(previous.kind)
        return cls(
            plan,
            parse_params(plan, dict(previous.params.get("plan", {}))),
            MeasureParams.model_validate(previous.params.get("measure", {})),
            previous.params.get("scale_calibration"),
            previous,
        )

    def runner(
        self,
        record: Record,
        *,
        devices: StationDevices | None,
        station: str,
        compute: MeasureBackend | None,
        jobs: int = 1,
    ) -> SessionRunner:
        """The session's runner (``devices`` only for a plan that needs them)."""
        return SessionRunner(
            record,
            self.plan,
            self.params,
            devices=devices if self.plan.needs else None,
            measure_params=self.measure,
            scale_calibration=self.scale_calibration,
            resume_session=self.previous,
            jobs=jobs,
            compute=compute,
            station=station,
        )


def run_session(
    kind: str | None = None,
    *,
    sim: bool | Mapping[str, Any] = False,
    config: str | Path | StationConfig | None = None,
    params: Mapping[str, Any] | None = None,
    assignments: Mapping[str, Any] | None = None,
    data: str | Path | None = None,
    database: str | None = None,
    resume: str | None = None,
    jobs: int = 1,
    compute: ComputeSpec | None = None,
    on_event: Callable[[EventRow], None] | None = None,
    on_runner: Callable[[SessionRunner], None] | None = None,
) -> SessionOutcome:
    """Run a session of ``kind`` (or ``resume`` one) and return its outcome.

    ``sim``: the simulated station (``True``, or a mapping of ``build_sim_station`` options);
    ``config``: a station configuration file or model; offline plans (sweep, reanalyse) need neither.
    ``params``: the plan's parameters; ``assignments``: measurement parameters (``--set``).
    ``compute``: where offline plans measure (``station.compute``); default: the configuration's
    ``[compute]``, else a local pool of ``jobs`` processes.
    ``on_runner`` gets the runner before it runs (to pause, stop or abort it from another thread).
    """
    cfg = config if isinstance(config, StationConfig) or config is None else load_config(config)
    record = open_record(data, database, cfg)
    try:
        if resume is not None:
            start = SessionStart.resume(record, resume)
        elif kind is None:
            raise PlanError(f"give a session kind ({', '.join(KIND_NAMES)}) or resume")
        else:

            def station_given(plan: Plan) -> None:
                if plan.needs and not sim and cfg is None:
                    raise ConfigurationError(f"a {kind} session drives hardware: give --sim or --config FILE")

            start = SessionStart.new(record, kind, params or {}, cfg, assignments, check=station_given)
        plan, previous = start.plan, start.previous
        if previous is not None and plan.needs and not sim and cfg is None:
            sim = previous.config.get("name") == "sim"
            if not sim:
                raise ConfigurationError(f"give --config FILE to resume {previous.id} on its station")
        devices: StationDevices | None = None
        if plan.needs and sim:
            # what the session needs on the table, the session asks for; the simulated operator puts it
            devices = open_sim_station(**(dict(sim) if isinstance(sim, Mapping) else {}))
        elif plan.needs:
            assert cfg is not None  # checked above
            devices = build_station(cfg)
        spec = compute or (cfg.compute.spec(jobs) if cfg is not None else ComputeSpec(jobs=jobs))
        backend = open_backend(spec)
        try:
            station = devices.config.name if devices is not None else (cfg.name if cfg else "default")
            runner = start.runner(record, devices=devices, station=station, compute=backend, jobs=jobs)
            if on_event is not None:
                runner.subscribe(on_event)
            if on_runner is not None:
                on_runner(runner)
            with terminal_prompts(devices) if devices is not None else contextlib.nullcontext():
                runner.run()
        finally:
            backend.close()
            if devices is not None:
                devices.close_owned()
        assert runner.session_id is not None
        return SessionOutcome.of(record.get_session(runner.session_id))
    finally:
        record.close()


def session_measure_params(
    record: Record,
    kind: str,
    plan_values: Mapping[str, Any],
    cfg: StationConfig | None,
    assignments: Mapping[str, Any] | None = None,
) -> tuple[MeasureParams, dict[str, Any] | None]:
    """A new session's measurement parameters and scale calibration record (``station run`` and the
    service alike): the station's scale calibration, the configuration's or source session's
    parameters, then ``assignments`` (``--set``)."""
    entry = get_kind(kind)
    source = (
        record.get_session(str(plan_values["session"]))
        if entry.remeasures_source and "session" in plan_values
        else None
    )
    calibration, cal_source = _calibration(record, cfg, station_file=entry.scale_calibrated)
    if source is not None:
        base = dict(source.params.get("measure", {}))
    else:
        base = dict(cfg.measure) if cfg is not None else {}
    params, cal_doc = measure_params_for(kind, base, dict(assignments or {}), calibration, cal_source)
    if cal_doc is None and source is not None and "groove_width_mm" not in field_names(assignments or {}):
        # the source's measurement parameters carry its scale calibration's groove width: so does its
        # record of where that width came from
        cal_doc = source.params.get("scale_calibration")
    return params, cal_doc


def _calibration(
    record: Record, cfg: StationConfig | None, *, station_file: bool
) -> tuple[scal.ScaleCalibration | None, Path | None]:
    """The configuration's scale calibration, else (``station_file``: for kinds it applies to) the
    station's own in the data directory, when there is one."""
    if cfg is not None and cfg.scale_calibration is not None:
        return scal.load(cfg.scale_calibration), cfg.scale_calibration
    path = scal.station_file(record.data_dir)
    if station_file and path.exists():
        return scal.load(path), path
    return None, None
