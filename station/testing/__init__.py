"""In-process fakes of every device, for fast plan and runner tests (the *mock* tier; ``sim/`` is the
realistic tier).

Each fake satisfies its protocol in ``station.devices``, acts at once, records every call in ``calls``
(``(method, args)`` tuples, in order) and can be told to fail: ``fail_on("move_joints", exc, nth=3)``
raises ``exc`` on the third call of that method. Assertion helpers (``assert_called``,
``assert_not_called``, ``calls_of``) keep test bodies short. ``FakeCamera`` serves the frames it is
given, or draws a crossed-groove artifact whose crossing moves with the fake robot and table
(``Scene``), so that the measurement core measures real positions in plan tests.
"""

from __future__ import annotations

from station.testing._camera import FakeCamera, Scene, draw_cross
from station.testing._robot import FakeRobot
from station.testing._sensor import FakeDistanceSensor
from station.testing._station import FakeStation
from station.testing._table import FakeTable

__all__ = ["FakeCamera", "FakeDistanceSensor", "FakeRobot", "FakeStation", "FakeTable", "Scene", "draw_cross"]
