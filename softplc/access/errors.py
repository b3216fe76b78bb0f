"""The access port's refusal: a request a host front-end made that is not carried out."""

from __future__ import annotations

from softplc.errors import SoftPLCError


class AccessError(SoftPLCError):
    """A refused read, write or command. `status` says what kind of refusal it is, with the
    HTTP numbers every front-end understands: 400 a bad request (unknown object, value out
    of range), 403 not allowed (read-only object or front-end), 404 no such thing (rung),
    503 the command queue is full (try again later)."""

    def __init__(self, message: str, status: int = 400):
        super().__init__(message)
        self.status = status


__all__ = ["AccessError"]
