"""The web API's error: a refused request and its HTTP status (the access port's error,
whose `status` is already an HTTP status)."""

from __future__ import annotations

from softplc.access.errors import AccessError

ApiError = AccessError

__all__ = ["ApiError"]
