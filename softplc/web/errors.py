"""The web API's error: a refused request and its HTTP status."""

from __future__ import annotations

from ..errors import SoftPLCError


class ApiError(SoftPLCError):
    """A request the API refuses; `status` is the HTTP status that goes with it."""

    def __init__(self, message: str, status: int = 400):
        super().__init__(message)
        self.status = status


__all__ = ["ApiError"]
