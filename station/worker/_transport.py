"""The pipe between the service and its station worker: messages, exceptions carried across as their
own types, and the worker's log records sent to the service."""

from __future__ import annotations

import importlib
import logging
import threading
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

from station.runner import (
    SessionError,
)

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------- exceptions over the pipe


def _pack_exception(exc: BaseException) -> tuple[str, str, tuple[Any, ...], dict[str, Any], str]:
    return (type(exc).__module__, type(exc).__qualname__, exc.args, dict(vars(exc)), str(exc))


def _unpack_exception(packed: tuple[str, str, tuple[Any, ...], dict[str, Any], str]) -> BaseException:
    """The same exception type with the same attributes (its ``__init__`` is not called again: many of
    the project's exceptions take other arguments than their message)."""
    module, qualname, args, attrs, text = packed
    try:
        cls: Any = importlib.import_module(module)
        for part in qualname.split("."):
            cls = getattr(cls, part)
        if not (isinstance(cls, type) and issubclass(cls, BaseException)):
            raise TypeError(qualname)
        exc: BaseException = cls.__new__(cls)
        BaseException.__init__(exc, *args)
        vars(exc).update(attrs)
        return exc
    except Exception:  # noqa: BLE001 - an exception type the front end cannot import
        return SessionError(f"{qualname}: {text}")


class _Pipe:
    """One end of the pipe; ``send`` from any thread (a Connection is not safe for concurrent sends)."""

    def __init__(self, conn: Connection) -> None:
        self.conn = conn
        self._lock = threading.Lock()

    def send(self, message: tuple[Any, ...]) -> None:
        with self._lock:
            self.conn.send(message)


class _PipeLogHandler(logging.Handler):
    """The worker's log records, formatted here, re-emitted by the front end's loggers."""

    def __init__(self, send: Callable[[tuple[Any, ...]], None]) -> None:
        super().__init__()
        self._send = send
        self._formatter = logging.Formatter()

    def emit(self, record: logging.LogRecord) -> None:
        try:
            doc = {
                "name": record.name,
                "levelno": record.levelno,
                "levelname": record.levelname,
                "msg": record.getMessage(),
                "pathname": record.pathname,
                "lineno": record.lineno,
                "funcName": record.funcName,
                "created": record.created,
                "msecs": record.msecs,
                "threadName": f"worker:{record.threadName}",
                "processName": "station-worker",
                "exc_text": self._formatter.formatException(record.exc_info) if record.exc_info else None,
            }
            self._send(("log", doc))
        except (OSError, ValueError):
            pass  # the front end has gone: nobody to tell
        except Exception:  # noqa: BLE001 - logging must not raise
            self.handleError(record)


def _emit_log(doc: dict[str, Any]) -> None:
    """A worker's log record, through the front end's logger of the same name."""
    record = logging.makeLogRecord(doc)
    logger = logging.getLogger(record.name)
    if logger.isEnabledFor(record.levelno):
        logger.handle(record)
