"""Build concrete devices by name without importing them.

Drivers (``drivers/``) and twins (``sim/``) register factories under the entry-point group
``station.devices`` with names ``KIND.NAME`` (``robot.crs_a465``, ``robot.sim``, ``camera.aravis`` ...),
so that the core never imports them (architecture.md, direction of dependencies).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from importlib.metadata import entry_points
from typing import Any

log = logging.getLogger(__name__)

DEVICE_GROUP = "station.devices"


class ConfigurationError(ValueError):
    """The station configuration names something that does not exist or cannot be built."""


def _factories() -> dict[str, Any]:
    return {ep.name: ep for ep in entry_points(group=DEVICE_GROUP)}


def available(kind: str) -> list[str]:
    """Names registered for ``kind`` (e.g. ``available("robot") == ["crs_a465", "sim"]``)."""
    prefix = kind + "."
    return sorted(name[len(prefix) :] for name in _factories() if name.startswith(prefix))


def factory(kind: str, name: str) -> Callable[..., Any]:
    """The registered factory for ``KIND.NAME``; ConfigurationError naming the choices if absent."""
    eps = _factories()
    key = f"{kind}.{name}"
    if key not in eps:
        choices = ", ".join(available(kind)) or "none registered (is the project installed with pip -e?)"
        raise ConfigurationError(f"no {kind} named {name!r}; available: {choices}")
    loaded = eps[key].load()
    if not callable(loaded):
        raise ConfigurationError(f"entry point {key} is not callable")
    return loaded


def build(kind: str, name: str, /, **options: Any) -> Any:
    """Build the device ``KIND.NAME`` with keyword ``options``."""
    log.debug("building %s.%s with %s", kind, name, sorted(options))
    return factory(kind, name)(**options)
