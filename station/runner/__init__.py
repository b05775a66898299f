"""The session runner: runs one plan over the station's devices, records everything, obeys the operator.

States: ``SessionState``, with their transitions in ``station.runner._states``.

* Every session (and every resume) starts at its plan's reference pose: when the arm is elsewhere, its
  first step is the arm's route there from where it is commanded (``station.arm_route``), checked in
  pre-flight with everything else; a plan that never moves the arm (validation) is refused instead.
* **Pause** takes effect at the next safe point (between steps); **resume** continues.
* **Stop** finishes the step in progress, returns the arm to the reference pose (along the same route),
  closes the devices.
* **Abort** stops the robot now through its latched stop, cancels the open operator prompt, and moves
  nothing more; the latch stays set on the driver.
* A device error fails the session: the robot is stopped, its position read again and recorded, and
  everything captured until then stays in the record.
* One session at a time per station (data directory), across processes: a ``station_lock`` that a dead
  owner's lock does not block. After a crash, ``resume`` continues after the last completed step, or
  from where the plan's resume rule says (``resume_from``: repeatability reruns the interrupted test).
* Gates: a result that fails one of its ``fail`` checks (``results.checks``) ends the session ``failed``
  with their messages, its results kept; a plan's ``check_progress`` stops it at once. A validation that
  succeeded writes the station's scale calibration before its state says so.

Every capture is stored (lossless, fsynced) before it is measured, and measured from the stored file, so
re-analysis of the record reproduces the live results bit for bit. Events (state changes, steps, images,
measurements, prompts, warnings, errors) are persisted with a per-session sequence number and a
station-wide id, by the session's journal (``Journal``), which alone writes the session's events and state
and calls the runner's listeners, in order and outside every lock of the runner (``station serve``'s worker
forwards them to the API's streams, ``station.worker``): a slow listener never holds up ``abort``.

Modules: ``_states`` (states, errors, progress), ``_runner`` (the lifecycle: ``SessionRunner``),
``_control`` (pause, resume, stop, abort), ``_journal`` (events and persisted state), ``_preflight`` (every
check before anything moves, and the route to the reference pose), ``_actions`` (the action executor: a
handler per action type), ``_store`` (the store pipeline and what analysis reads back), ``_devices`` (the
session's hold on the devices), ``_resume`` (the session created, its steps on a resume, the plan's
context), ``_outcome`` (the analysis and what a passed validation leaves).
"""

from station.plans._recorded import FRAMES_PER_ATTEMPT, stored_captures
from station.runner._actions import HANDLERS, ActionExecutor, Handler, require, step_moves
from station.runner._control import SessionControl
from station.runner._journal import Journal, reconcile
from station.runner._preflight import find_problems, route_to_reference
from station.runner._resume import SessionSteps, camera_height_function, plan_context, session_steps
from station.runner._runner import SessionRunner
from station.runner._states import (
    ACTIVE_STATES,
    EARLY_FAILURE_CAPTURES,
    FINAL_STATES,
    PRELUDE_BASE,
    PreflightError,
    Progress,
    SessionError,
    SessionState,
    software_info,
)
from station.runner._store import Grabbed, StepRun, StorePipeline

__all__ = [
    "ACTIVE_STATES",
    "EARLY_FAILURE_CAPTURES",
    "FINAL_STATES",
    "FRAMES_PER_ATTEMPT",
    "HANDLERS",
    "PRELUDE_BASE",
    "ActionExecutor",
    "Grabbed",
    "Handler",
    "Journal",
    "PreflightError",
    "Progress",
    "SessionControl",
    "SessionError",
    "SessionRunner",
    "SessionState",
    "SessionSteps",
    "StepRun",
    "StorePipeline",
    "camera_height_function",
    "find_problems",
    "plan_context",
    "reconcile",
    "require",
    "route_to_reference",
    "session_steps",
    "software_info",
    "step_moves",
    "stored_captures",
]
