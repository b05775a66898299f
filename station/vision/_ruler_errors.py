"""The ruler measurement's refusals: each says what is wrong with the view and what to do.

All are ``MeasurementError``s, so that ``station measure`` reports them as it does the cross's, one
line per file with its ``code``.
"""

from __future__ import annotations

from station.vision._errors import MeasurementError


class OffRulerError(MeasurementError):
    """No ruler pattern in view, or the pattern runs out of the frame across the ruler."""

    code = "off_ruler"


class TooFewGraduationsError(MeasurementError):
    """The ruler is in view over too short a stretch (an end of the ruler, a steep angle)."""

    code = "too_few_graduations"


class CodeUnreadableError(MeasurementError):
    """Too few of the code track's cells can be read (dirt, low contrast, too short a stretch)."""

    code = "code_unreadable"


class CodeInconsistentError(MeasurementError):
    """The cells read match no place of the ruler's code (another ruler, a mirrored image, damage)."""

    code = "code_inconsistent"
