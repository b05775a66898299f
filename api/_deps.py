"""Dependency wiring: the service lives on ``app.state``, never in a module global."""

from __future__ import annotations

from fastapi import Request

from api._service import StationService


def service_of(request: Request) -> StationService:
    service: StationService = request.app.state.service
    return service
