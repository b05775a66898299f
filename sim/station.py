"""The whole simulated station in one object: controller twin, world, flange camera, table operator.

The arm is the controller twin on a real pseudo-terminal (talk to it with the real driver through
``port``); the world follows the twin's attained joints, so a joint move changes what the camera
sees; the operator answers the manual table's prompts on ``broker`` by turning the world's
micrometers. Start it at the world's reference pose, where the camera looks down at the crossing.
"""

from __future__ import annotations

from typing import Any

from sim.camera import SimCamera
from sim.controller import ControllerTwin
from sim.operator import SimOperator
from sim.world import World, WorldSpec
from station.prompts import PromptBroker


class SimStation:
    """Twin, world, camera and operator wired together; close it when done (or use ``with``).

    Parameters
    ----------
    spec
        The world (optics, table, preset); the twin starts at ``spec.reference_joints_deg``.
    seed
        Seeds the twin's repeatability error and the camera noise.
    twin_options
        Further :class:`sim.controller.TwinSettings` fields (``time_scale``, ``repeat_sigma_deg`` ...).
    """

    def __init__(
        self,
        spec: WorldSpec | None = None,
        *,
        seed: int = 0,
        operator_delay_s: float = 0.0,
        camera_frame_rate_hz: float = 0.0,
        **twin_options: Any,
    ) -> None:
        world_spec = spec or WorldSpec()
        options = {"time_scale": 100.0, "seed": seed, **twin_options}
        options.setdefault("start_pose_deg", world_spec.reference_joints_deg)
        self.twin = ControllerTwin(**options).start()
        self.world = World(world_spec, joints=self.twin.arm.actual_exact)
        self.camera = SimCamera(self.world, seed=seed, frame_rate_hz=camera_frame_rate_hz)
        self.broker = PromptBroker()
        self.operator = SimOperator(self.broker, self.world, delay_s=operator_delay_s).start()

    @property
    def port(self) -> str:
        """The pty the controller twin serves: open the robot driver on it."""
        return self.twin.port

    def close(self) -> None:
        self.operator.close()
        self.camera.close()
        self.twin.close()

    def __enter__(self) -> SimStation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
