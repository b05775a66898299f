"""The session's hold on the station's devices: connected and closed, the arm stopped at once on an abort
or a device error and its position read again, returned to the reference pose on a stop."""

from __future__ import annotations

import contextlib
import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from station.arm_route import go_to_reference, max_step_of
from station.config import StationDevices
from station.devices import DeviceError
from station.prompts import PromptError
from station.runner._journal import Journal

log = logging.getLogger("station.runner")

DEVICE_NAMES = ("robot", "camera", "table", "distance_sensor")


@dataclass
class SessionDevices:
    """The devices of one session (``None`` offline) and the journal that records what happens to them."""

    devices: StationDevices | None
    journal: Journal
    stop_sent: threading.Event = field(default_factory=threading.Event)
    """Set once an abort's robot stop has been sent (or failed): the port is not closed under it."""

    def connect(self, stack: contextlib.ExitStack, *, aborted: Callable[[], bool]) -> None:
        """Connect every device, each closed by ``stack`` (``aborted()``: wait for an abort's stop)."""
        devices = self.devices
        if devices is None:
            return
        for name in DEVICE_NAMES:
            device = getattr(devices, name)
            if device is None:
                continue
            device.connect()
            stack.callback(self._close, name, device, aborted)
        identities = devices.identities()
        self.journal.emit("connected", {"devices": identities})
        if self.journal.session_id is not None:  # the row had only what the configuration says
            self.journal.record.set_identities(self.journal.session_id, identities)

    def _close(self, name: str, device: Any, aborted: Callable[[], bool]) -> None:
        if name == "robot" and aborted():
            # the runner may reach its clean-up while abort() is still writing the stop: never close
            # the port under it
            self.stop_sent.wait(5.0)
        try:
            device.close()
        except Exception as exc:  # noqa: BLE001 - the others must still be closed
            self.journal.emit("warning", {"message": f"closing the {name} failed: {exc}"})

    def stop_now(self) -> None:
        """An abort's stop (latched on the driver), from the caller's thread; never waits for a listener."""
        robot = self.devices.robot if self.devices is not None else None
        if robot is not None:
            try:
                robot.stop()
            except Exception as exc:  # noqa: BLE001 - the prompt must still be cancelled
                log.error("abort: robot stop failed: %s (use the E-stop)", exc)
                message = f"robot stop failed during abort: {exc}; use the E-stop"
                self.journal.emit("error", {"message": message}, wait=False)
        self.stop_sent.set()

    def stop_after(self, exc: BaseException) -> None:
        """After a device error (or Ctrl-C): stop the arm and record where it is."""
        robot = self.devices.robot if self.devices is not None else None
        if robot is not None and isinstance(exc, DeviceError | KeyboardInterrupt | SystemExit):
            with contextlib.suppress(Exception):
                robot.stop()
            self.reread_position("error")

    def reread_position(self, why: str) -> None:
        robot = self.devices.robot if self.devices is not None else None
        if robot is None:
            return
        try:
            pos = robot.where()
        except Exception as exc:  # noqa: BLE001 - recorded; the operator must look at the arm
            self.journal.emit(
                "warning", {"message": f"after the {why}, the position could not be read: {exc}"}
            )
            return
        self.journal.emit("position", {"after": why, "joints_deg": list(pos.joints_deg)})

    def return_to_reference(self) -> None:
        """A stopped session's arm back to the reference pose, along the same route as it came."""
        devices = self.devices
        reference = devices.reference_joints_deg if devices is not None else None
        if devices is None or devices.robot is None or reference is None:
            return
        safety = devices.config.robot.safety if devices.config.robot is not None else None
        try:
            done = go_to_reference(devices.robot, reference, max_step_deg=max_step_of(safety))
            self.journal.emit("returned", {"joints_deg": list(reference), "moves": done.moves})
        except DeviceError as exc:
            self.journal.emit("warning", {"message": f"could not return to the reference pose: {exc}"})

    def cancel_prompt(self, reason: str) -> None:
        """Cancel the operator prompt that is open, if any."""
        if self.devices is None:
            return
        prompt = self.devices.broker.current(pending=True)
        if prompt is not None:
            with contextlib.suppress(PromptError):
                self.devices.broker.cancel(prompt.id, reason=reason, by="runner")
