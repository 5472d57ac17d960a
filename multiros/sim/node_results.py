"""Result codes and reply helpers shared by the simulation node's service handlers.

``simulation_interfaces/msg/Result`` codes, :func:`fail` / :func:`ok` to fill a reply's result,
and :func:`guarded`, the safety net that turns an unexpected exception in a handler into
``RESULT_OPERATION_FAILED``.
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable
from typing import Any

from multiros.sim.distro_adapters import get_message

# The node's logger: unexpected handler errors are logged as the node's own.
_logger = logging.getLogger("multiros.sim.node")

Result = get_message("simulation_interfaces/msg/Result")

OK, NOT_FOUND, INCORRECT_STATE, FAILED = (
    Result.RESULT_OK,
    Result.RESULT_NOT_FOUND,
    Result.RESULT_INCORRECT_STATE,
    Result.RESULT_OPERATION_FAILED,
)


def fail(result: Any, code: int, message: str) -> None:
    """Set a reply's ``result`` to ``code`` with ``message``."""
    result.result = code
    result.error_message = message


def ok(result: Any) -> None:
    """Set a reply's ``result`` to RESULT_OK."""
    result.result = OK
    result.error_message = ""


def guarded(handler: Callable[[Any, Any, Any], Any]) -> Callable[[Any, Any, Any], Any]:
    """An unexpected exception in a service handler becomes RESULT_OPERATION_FAILED with a
    message (and a log entry), never a traceback to the caller or a dead node."""

    @functools.wraps(handler)
    def wrapper(self: Any, request: Any, response: Any) -> Any:
        try:
            return handler(self, request, response)
        except Exception as exc:  # the handler's own errors are mapped inside; this is the safety net
            _logger.exception("%s failed unexpectedly", handler.__name__.removeprefix("_srv_"))
            result = getattr(response, "result", None)
            if result is not None:
                detail = f"{type(exc).__name__}: {exc}"
                fail(result, FAILED, f"{handler.__name__.removeprefix('_srv_')} failed unexpectedly: {detail[:400]}")
            return response

    return wrapper
