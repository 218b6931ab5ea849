"""Start the real daemon (uvicorn on a loopback port, in a thread) for end-to-end tests."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx

from service.daemon import (
    BackgroundServer,
    Daemon,
    bind_socket,
    build_daemon,
    make_server,
    serve_in_thread,
)
from service.demo import demo_settings


@dataclass
class RunningServer:
    daemon: Daemon
    port: int
    token: str | None

    @property
    def http(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    @property
    def ws(self) -> str:
        return f"ws://127.0.0.1:{self.port}"

    def headers(self) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.token}"} if self.token else {}

    def get(self, path: str, **kw: Any) -> httpx.Response:
        headers = {**self.headers(), **kw.pop("headers", {})}
        return httpx.get(self.http + path, headers=headers, timeout=10, **kw)

    def wait_for_seq(self, seq: int, timeout: float = 30.0) -> None:
        deadline = time.time() + timeout
        while self.daemon.hub.latest().seq < seq:
            if time.time() > deadline:
                raise TimeoutError(f"pipeline did not reach seq {seq}: {self.daemon.health()}")
            time.sleep(0.02)


def serve_with_static(
    daemon: Daemon, port: int = 0, static: dict[str, Path] | None = None
) -> BackgroundServer:
    """``service.daemon.serve_in_thread`` plus test-only static mounts on the daemon's own app.

    Client example pages (``examples/web``) are mounted here so a browser loads them from the
    daemon's origin: a page on another origin would be refused by the Origin checks.
    """
    from fastapi.staticfiles import StaticFiles

    if not static:
        return serve_in_thread(daemon, port=port)
    sock = bind_socket("127.0.0.1", port)
    server = make_server(daemon, "127.0.0.1", sock.getsockname()[1])
    for prefix, directory in (static or {}).items():
        server.config.app.mount(prefix, StaticFiles(directory=directory), name=prefix)
    thread = threading.Thread(
        target=server.run, kwargs={"sockets": [sock]}, name="uvicorn", daemon=True
    )
    thread.start()
    deadline = time.time() + 60
    while not server.started:
        if time.time() > deadline or not thread.is_alive():
            sock.close()
            raise RuntimeError("the HTTP server did not start")
        time.sleep(0.02)
    return BackgroundServer(daemon, sock.getsockname()[1], server, thread, sock)


@contextmanager
def running_server(
    *, port: int = 0, static: dict[str, Path] | None = None, **settings: Any
) -> Iterator[RunningServer]:
    """The demo daemon (synthetic scene, shipped model) on a loopback port (0: a free one)."""
    token = settings.pop("token", None)
    model_dir = settings.pop("model_dir", None)
    config = demo_settings(host="127.0.0.1", **settings)
    if model_dir:
        config = config.model_copy(update={"model_dir": Path(model_dir)})
    daemon = build_daemon(config)
    daemon.token = token
    background = serve_with_static(daemon, port, static)
    try:
        yield RunningServer(daemon, background.port, token)
    finally:
        background.stop()
