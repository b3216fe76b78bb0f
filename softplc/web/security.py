"""Who may talk to the web monitor: the Host allow-list, the Origin check and the tokens.

- **Host** (every route and the websocket): a browser tricked by DNS rebinding sends the
  attacker's name (`Host: evil.example:8020`) to this server; only names this machine
  answers to are accepted: `localhost`, the machine's host name, any IP address literal
  (a page cannot rebind an address: its origin is that address) and the names the user
  allows (`--web-allow-host`, `*` = any, for a reverse proxy that checks names itself).
- **Origin** (when the browser sends one): the page must come from this server, by an
  allowed name.
- **Tokens**: on loopback, reads are free and changes need the token if one is set; beyond
  loopback every request needs a token: the full one, or the read-only one (`--web-read-
  token`) for reads (GET routes, `POST /api/read`, the websocket). A token comes as
  `Authorization: Bearer T`, `?token=T` or the cookie set when a page was opened with
  `?token=T` (HttpOnly, SameSite=Strict: another site's page never sends it).
"""

from __future__ import annotations

import hmac
import ipaddress
import socket
from collections.abc import Iterable
from typing import Any
from urllib.parse import urlsplit

from softplc.web.errors import ApiError

COOKIE = "softplc_token"


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _hostname(hostport: str) -> str | None:
    """The name in a Host header or an origin's netloc, lower case; None: malformed."""
    try:
        parts = urlsplit("//" + hostport)
        name = parts.hostname
        parts.port  # noqa: B018 (raises ValueError on a bad port)
    except ValueError:
        return None
    return name.rstrip(".") if name else None


def _is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


class Guard:
    """The checks every request goes through (`check`), in the server's middleware."""

    def __init__(self, host: str, token: str | None = None, read_token: str | None = None,
                 allowed_hosts: Iterable[str] = ()):
        self.loopback = is_loopback(host)
        self.token = token
        self.read_token = read_token
        names = {h.strip().lower().rstrip(".") for h in allowed_hosts if h.strip()}
        self.any_host = "*" in names
        self.names = names | {"localhost", socket.gethostname().lower()}

    @property
    def reads_need_token(self) -> bool:
        return not self.loopback and (self.token is not None or self.read_token is not None)

    def host_allowed(self, name: str | None) -> bool:
        if name is None:
            return False
        return self.any_host or name in self.names or _is_ip(name)

    def check(self, request: Any, change: bool) -> str | None:
        """Raise ApiError (403 for a foreign Host or Origin, 401 for a missing or wrong
        token) unless `request` may go on; `change`: it changes something. Returns the
        token the request gave in its query, if valid (the server sets the cookie)."""
        host = request.headers.get("Host")
        if host is not None and not self.host_allowed(_hostname(host)):
            raise ApiError(f"host {host!r} is not allowed: open the monitor by this "
                           f"machine's name or address, or start the daemon with "
                           f"--web-allow-host NAME", 403)
        origin = request.headers.get("Origin")
        if origin is not None:
            netloc = urlsplit(origin).netloc
            if (host is not None and netloc != host) or not self.host_allowed(
                    _hostname(netloc)):
                raise ApiError(f"requests from the page of {origin} are refused", 403)
        return self._check_token(request, change)

    def _check_token(self, request: Any, change: bool) -> str | None:
        wanted = [self.token] if change else [self.token, self.read_token]
        wanted = [t for t in wanted if t is not None]
        if not wanted or (not change and not self.reads_need_token):
            return None
        query = request.query.get("token", "")
        given = request.headers.get("Authorization", "").removeprefix("Bearer ").strip() \
            or query or request.cookies.get(COOKIE, "")
        what = "changes" if change else "every request beyond loopback"
        if not given:
            raise ApiError(f"this monitor needs a token for {what}: send 'Authorization: "
                           f"Bearer TOKEN' or open the URL with ?token=TOKEN (printed when "
                           f"the daemon started)", 401)
        if not any(hmac.compare_digest(given.encode(), t.encode()) for t in wanted):
            if change and self.read_token is not None \
                    and hmac.compare_digest(given.encode(), self.read_token.encode()):
                raise ApiError("the read-only token cannot change anything", 403)
            raise ApiError("wrong token", 401)
        return query or None


__all__ = ["COOKIE", "Guard", "is_loopback"]
