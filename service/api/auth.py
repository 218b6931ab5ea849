"""The API token: one check for REST routes (a FastAPI dependency) and WebSockets.

With a token configured, every ``/v1`` route and ``/metrics`` needs it, as
``Authorization: Bearer TOKEN`` or ``?token=TOKEN`` (browsers cannot set WebSocket headers).
REST answers 401; a WebSocket is accepted and closed with :data:`WS_AUTH_CLOSE` so that clients
can tell an auth failure from a network error. The comparison is constant-time.
"""

from __future__ import annotations

import secrets
from collections.abc import Mapping

from fastapi import Depends, HTTPException, Request
from fastapi.params import Depends as DependsParam

WS_AUTH_CLOSE = 4401


def token_of(headers: Mapping[str, str], query: Mapping[str, str]) -> str | None:
    """The token a request carries: the Bearer header first, else ``?token=``."""
    auth = headers.get("authorization", "")
    if auth.lower().startswith("bearer "):
        return auth[7:].strip()
    return query.get("token")


class TokenCheck:
    """``expected`` None: the API is open. ``secured`` goes into a route's ``dependencies``."""

    def __init__(self, expected: str | None) -> None:
        self.expected = expected
        self.secured: list[DependsParam] = [Depends(self.require)]

    def allows(self, headers: Mapping[str, str], query: Mapping[str, str]) -> bool:
        if self.expected is None:
            return True
        given = token_of(headers, query)
        return given is not None and secrets.compare_digest(given.encode(), self.expected.encode())

    def require(self, request: Request) -> None:
        if not self.allows(request.headers, request.query_params):
            raise HTTPException(401, "missing or wrong token", {"WWW-Authenticate": "Bearer"})
