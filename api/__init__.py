"""The station as a service: a REST API with live events and an operator page (``station serve``).

``create_app(service, access)`` builds the FastAPI app over a :class:`StationService`; routers are thin
over the service, which uses the runner, the record and the prompt broker of ``station/``.
``server_config(app, limits)`` is uvicorn's configuration with the server's own limits (header timeout,
connection limit), and ``listen(host, port)`` the socket it serves.
"""

from api._app import create_app
from api._auth import Access, TokenError, is_loopback, resolve_token
from api._edge import AllowedHosts
from api._server import ListenError, ServeLimits, listen, server_config
from api._service import StationService
from api._settings import ServiceSettings

__all__ = [
    "Access",
    "AllowedHosts",
    "ListenError",
    "ServeLimits",
    "ServiceSettings",
    "StationService",
    "TokenError",
    "create_app",
    "is_loopback",
    "listen",
    "resolve_token",
    "server_config",
]
