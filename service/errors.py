"""Errors of the service layer (under :class:`navigation.errors.ServiceError`).

Two kinds of bad input reach the service over the bus: sensor messages that cannot be used
(:class:`MessageError`: dropped with a warning in ``status.message``) and task requests that
cannot be accepted (:class:`TaskRejected`: answered with the contract's typed error reply).
Neither ever escapes to Zenoh.
"""

from __future__ import annotations

from enum import Enum

from navigation.errors import ServiceError

__all__ = ["ServiceError", "MessageError", "StaleMessageError", "TaskErrorCode", "TaskRejected"]


class MessageError(ServiceError, ValueError):
    """A bus message that does not parse, has the wrong fields or non-finite numbers.

    Attributes
    ----------
    key : str
        The bus key suffix it arrived on (``"scan"``, ``"points"``, ``"pose"``, ``"task"``).
    field : str or None
        The offending field, when known.
    """

    def __init__(self, key: str, reason: str, field: str | None = None):
        self.key = key
        self.reason = reason
        self.field = field
        super().__init__(f"{key}: {reason}")


class StaleMessageError(MessageError):
    """A message whose stamp is not newer than the last accepted one on the same key
    (duplicated or out of order)."""


class TaskErrorCode(str, Enum):
    """The ``error.code`` values of a refused ``task`` query (FORMATS.md bus contract)."""

    PARSE_ERROR = "parse_error"
    UNKNOWN_REGION = "unknown_region"
    UNSATISFIABLE = "unsatisfiable"
    INVALID_REQUEST = "invalid_request"


class TaskRejected(ServiceError, ValueError):
    """A task request that the service refuses; the running mission is unaffected.

    Attributes
    ----------
    code : TaskErrorCode
    message : str
    """

    def __init__(self, code: TaskErrorCode | str, message: str):
        self.code = TaskErrorCode(code)
        self.message = str(message)
        super().__init__(f"{self.code.value}: {self.message}")

    def to_reply(self) -> dict:
        """The contract's error reply ``{"ok": false, "error": {"code", "message"}}``."""
        return {"ok": False, "error": {"code": self.code.value, "message": self.message}}
