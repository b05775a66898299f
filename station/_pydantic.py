"""One way to say what a pydantic validation error found, for one-line error messages."""

from __future__ import annotations

from pydantic import ValidationError


def problems(exc: ValidationError, top: str = "(top level)") -> str:
    """``"field.sub: message; other: message"``; ``top`` names an error without a location."""
    return "; ".join(
        f"{'.'.join(str(x) for x in e['loc']) or top}: {e['msg']}" for e in exc.errors(include_url=False)
    )
