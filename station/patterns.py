"""Table patterns for validation sessions (the seed's section 4, Figure 13), in um, table axes."""

from __future__ import annotations

#: The seed's step: 0.0002 in on the micrometers, 5.08 um.
STEP_UM = 25.4 * 1000 * 0.0002
#: Steps along each side of the seed's square: 10 steps of 5.08 um, a 50.8 um square.
STEPS_PER_SIDE = 10


def validation_pattern_um(
    step_um: float = STEP_UM, steps_per_side: int = STEPS_PER_SIDE
) -> list[tuple[float, float]]:
    """Commanded table positions of the seed's square path (Figure 13), um, table axes.

    Start at (0, 0), then ``steps_per_side`` steps each of +x, +y, -x, -y; the return to the start
    is not repeated: ``4 * steps_per_side`` positions (40 by default, a 50.8 um square).
    """
    if steps_per_side < 1:
        raise ValueError(f"steps_per_side must be at least 1, got {steps_per_side}")
    n = steps_per_side
    pts: list[tuple[int, int]] = [(0, 0)]
    for dx, dy in ((1, 0), (0, 1), (-1, 0), (0, -1)):
        for _ in range(n):
            x, y = pts[-1]
            pts.append((x + dx, y + dy))
    return [(x * step_um, y * step_um) for x, y in pts[:-1]]
