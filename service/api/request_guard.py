"""Browser-facing guard: Host and Origin checks, JSON-only state changes, bounded bodies.

Why: the daemon listens on loopback without a token by default, and every web page open in a
browser on the same machine can reach loopback. Without these checks such a page could read the
position stream (WebSockets are not covered by CORS), fire body-less POSTs as "simple" cross-site
requests, or use DNS rebinding (a name that first resolves to the attacker, then to 127.0.0.1) to
read REST answers as if it were same-origin. What careful local daemons do, in this order:

1. **Host.** A request whose ``Host`` names a host other than an IP literal, ``localhost``, this
   machine's name, the bind address or an ``allowed_hosts`` entry is refused (403): DNS rebinding
   always arrives with the attacker's name in ``Host``. No ``Host`` (HTTP/1.0 tools) is allowed.
2. **Origin.** Browsers send ``Origin`` on WebSocket handshakes and on cross-origin requests. One
   that is neither the daemon's own (``scheme://`` + the request's ``Host``) nor listed in
   ``allowed_origins`` is refused: a WebSocket is closed before it is accepted (the handshake gets
   403), any HTTP request gets 403. Requests without ``Origin`` (game engines, Python, curl) are
   not from a web page and pass; ``"*"`` in ``allowed_origins`` turns the check off.
3. **JSON bodies.** POST/PUT/PATCH/DELETE on a route that takes them need ``Content-Type:
   application/json`` (415 otherwise): a cross-site HTML form cannot send that type, and a script
   can only after a CORS preflight, which the daemon never grants. A method the path does not
   have is left to the app, which answers 405 (or 404): the route table (``routes``) says which.
4. **Size.** Request bodies above ``max_body`` bytes are refused (413): at once from
   ``Content-Length``, else (chunked) while the body is read here, before the app sees any of
   it. Read here because FastAPI turns any error raised while it reads a body into a 400.
"""

from __future__ import annotations

import ipaddress
import socket
from collections.abc import Iterable, Sequence
from typing import Any
from urllib.parse import urlsplit

from pydantic import BaseModel, ConfigDict
from starlette.routing import BaseRoute, Match

from service.api.errors import error_response

MAX_BODY_BYTES = 1 << 20  # settings and floor marks are a few kB; 1 MiB is generous
STATE_CHANGING = {"POST", "PUT", "PATCH", "DELETE"}


class EmptyBody(BaseModel):
    """The body of a state-changing route without parameters: a JSON object, ``{}`` (rule 3)."""

    model_config = ConfigDict(extra="forbid", strict=True)


def host_name(host_header: str) -> str:
    """The name part of a ``Host`` value: ``[::1]:8765`` → ``::1``, ``a.b:80`` → ``a.b``."""
    value = host_header.strip().lower()
    if value.startswith("["):
        return value[1:].split("]", 1)[0]
    return value.rsplit(":", 1)[0] if value.count(":") == 1 else value


def _is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


def normalise_origin(origin: str) -> str:
    """``HTTP://Example.com:80/`` → ``http://example.com:80`` (scheme and netloc only)."""
    parts = urlsplit(origin.strip())
    return f"{parts.scheme.lower()}://{parts.netloc.lower()}"


class RequestGuard:
    """ASGI middleware applying the module's four rules before the app sees a request."""

    def __init__(
        self,
        app: Any,
        *,
        bind_host: str = "127.0.0.1",
        allowed_hosts: Iterable[str] = (),
        allowed_origins: Iterable[str] = (),
        max_body: int = MAX_BODY_BYTES,
        routes: Sequence[BaseRoute] = (),
    ) -> None:
        self.app = app
        self.max_body = max_body
        self.routes = routes  # the app's route table (the live list: routes added later count)
        hosts = {h.strip().lower() for h in allowed_hosts}
        self.any_host = "*" in hosts
        machine = socket.gethostname().lower()
        self.hosts = hosts | {"localhost", machine, f"{machine}.local", bind_host.lower()}
        origins = {o.strip() for o in allowed_origins}
        self.any_origin = "*" in origins
        self.origins = {normalise_origin(o) for o in origins if o != "*"}

    def host_allowed(self, host: str | None) -> bool:
        if host is None or self.any_host:
            return True
        name = host_name(host)
        return _is_ip(name) or name in self.hosts or name.endswith(".localhost")

    def origin_allowed(self, origin: str | None, host: str | None) -> bool:
        if origin is None or self.any_origin:
            return True
        own = {f"http://{host.lower()}", f"https://{host.lower()}"} if host else set()
        value = normalise_origin(origin)
        return value in own or value in self.origins

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope["headers"]}
        host, origin = headers.get("host"), headers.get("origin")
        problem, status = None, 403
        if not self.host_allowed(host):
            problem = (
                f"host '{host_name(host or '')[:80]}' is not allowed (DNS-rebinding guard); "
                "add it to allowed_hosts"
            )
        elif not self.origin_allowed(origin, host):
            problem = f"origin '{(origin or '')[:80]}' is not allowed; add it to allowed_origins"
        elif scope["type"] == "http" and scope["method"] in STATE_CHANGING and self._routed(scope):
            kind = headers.get("content-type", "").split(";")[0].strip().lower()
            if kind != "application/json":
                problem, status = (
                    "this route takes a JSON body (Content-Type: application/json)",
                    415,
                )
        if problem is None and scope["type"] == "http":
            if _length(headers.get("content-length")) > self.max_body:
                problem, status = f"request body larger than {self.max_body} bytes", 413
            else:
                body = await self._read_body(receive)
                if body is None:
                    problem, status = f"request body larger than {self.max_body} bytes", 413
                else:
                    receive = _replay(body, receive)
        if problem is not None:
            await self._refuse(scope, receive, send, status, problem)
            return
        await self.app(scope, receive, send)

    def _routed(self, scope: dict) -> bool:
        """Whether a route takes this method at this path (with no route table: assume so)."""
        if not self.routes:
            return True
        return any(route.matches(scope)[0] == Match.FULL for route in self.routes)

    async def _refuse(self, scope: dict, receive: Any, send: Any, status: int, text: str) -> None:
        if scope["type"] == "websocket":
            await receive()  # websocket.connect
            await send({"type": "websocket.close", "code": 1008})  # before accept: HTTP 403
            return
        await error_response(status, text)(scope, receive, send)

    async def _read_body(self, receive: Any) -> bytes | None:
        """The whole request body, or None once it passes ``max_body`` (then unread further:
        the refusal closes the connection). A disconnect ends it as an empty body."""
        chunks: list[bytes] = []
        size = 0
        while True:
            message = await receive()
            if message["type"] != "http.request":
                return b""
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > self.max_body:
                return None
            chunks.append(chunk)
            if not message.get("more_body", False):
                return b"".join(chunks)


def _replay(body: bytes, receive: Any) -> Any:
    """``receive`` for the app: the body read by the guard, then the server's own messages
    (the disconnect the app may wait for)."""
    pending = [{"type": "http.request", "body": body, "more_body": False}]

    async def replayed() -> dict:
        return pending.pop() if pending else await receive()

    return replayed


def _length(value: str | None) -> int:
    """Content-Length as a number (the HTTP parser has already refused malformed ones)."""
    return int(value) if value and value.strip().isdigit() else 0
