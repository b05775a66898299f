"""The station as a service: a REST API with live events and an operator page (``station serve``).

``create_app(service, access)`` builds the FastAPI app over a :class:`StationService`; routers are thin
over the service, which uses the runner, the record and the prompt broker of ``station/``.
"""

from api._app import create_app
from api._auth import Access, is_loopback, resolve_token
from api._service import ServiceSettings, StationService

__all__ = ["Access", "ServiceSettings", "StationService", "create_app", "is_loopback", "resolve_token"]
