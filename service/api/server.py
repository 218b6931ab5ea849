"""Serving a built daemon with uvicorn: bind first (a taken port is one line), then run.

``momloc serve``/``demo`` call :func:`run_server`; tests and benchmarks :func:`serve_in_thread`.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from common.errors import MomlocError
from service.api.app import create_app
from service.api.state import Daemon

log = logging.getLogger("momloc")
GRACEFUL_SHUTDOWN_S = 3


def bind_socket(host: str, port: int) -> socket.socket:
    """Listen on host:port now, so a taken port is a one-line user error, not a traceback."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
        sock.listen(2048)  # connections made right after the banner wait in the backlog
    except OSError as error:
        sock.close()
        raise MomlocError(f"cannot listen on {host}:{port} ({error.strerror})") from None
    sock.set_inheritable(True)
    return sock


def make_server(daemon: Daemon, host: str, port: int) -> Any:
    """A uvicorn server for ``daemon`` (run it with ``server.run(sockets=[sock])``)."""
    import uvicorn

    config = uvicorn.Config(
        create_app(daemon),
        host=host,
        port=port,
        log_level="warning",
        ws="websockets-sansio",
        ws_ping_interval=daemon.ping_interval,
        ws_ping_timeout=daemon.ping_timeout,
        # snapshots are a few hundred bytes: per-client zlib costs more CPU than it saves
        ws_per_message_deflate=False,
        # SIGTERM must stop the daemon within seconds, whatever a client is doing (a slow body,
        # a long request): open connections get this long, then they are cut
        timeout_graceful_shutdown=GRACEFUL_SHUTDOWN_S,
    )
    return uvicorn.Server(config)


def run_server(daemon: Daemon, host: str, port: int, on_ready: Any = None) -> None:
    """Bind, announce, and serve until interrupted (uvicorn owns signals and the loop)."""
    sock = bind_socket(host, port)
    server = make_server(daemon, host, port)
    if on_ready is not None:
        on_ready(sock.getsockname()[1])
    try:
        server.run(sockets=[sock])
    except KeyboardInterrupt:
        # uvicorn shut down on SIGINT/SIGTERM, then re-raised it to the handlers it found
        # (service.stop_signals): for a daemon that is the normal end, exit 0
        log.info("momloc: stopped")
    _exit_soon_if_stuck(GRACEFUL_SHUTDOWN_S + 5)


def _exit_soon_if_stuck(seconds: float) -> None:
    """After serving, make sure the process ends: a request still running in a worker thread
    (those threads are not daemons) would otherwise keep it alive after SIGTERM."""

    def deadline() -> None:
        time.sleep(seconds)
        log.warning("momloc: a request was still running %.0f s after stopping; exiting", seconds)
        logging.shutdown()
        os._exit(0)

    threading.Thread(target=deadline, name="momloc-exit-deadline", daemon=True).start()


@dataclass
class BackgroundServer:
    """A daemon served by uvicorn in a thread (tests and benchmarks)."""

    daemon: Daemon
    port: int
    server: Any
    thread: threading.Thread
    sock: socket.socket

    def stop(self) -> None:
        self.server.should_exit = True
        self.thread.join(timeout=15)
        self.sock.close()


def serve_in_thread(
    daemon: Daemon,
    host: str = "127.0.0.1",
    port: int = 0,
    *,
    static: Mapping[str, Path] | None = None,
) -> BackgroundServer:
    """Start serving ``daemon`` on host:port (0: any free port); returns once it accepts.

    ``static`` mounts extra folders (URL prefix -> folder) on the daemon's own app: the client
    example pages (``examples/web``) are served from the daemon's origin, since a page from
    another origin would be refused by the Origin checks (``service.api.request_guard``).
    """
    sock = bind_socket(host, port)
    server = make_server(daemon, host, sock.getsockname()[1])
    if static:
        from fastapi.staticfiles import StaticFiles

        for prefix, directory in static.items():
            server.config.app.mount(prefix, StaticFiles(directory=directory), name=prefix)
    thread = threading.Thread(
        target=server.run, kwargs={"sockets": [sock]}, name="uvicorn", daemon=True
    )
    thread.start()
    deadline = time.time() + 60
    while not server.started:
        if time.time() > deadline or not thread.is_alive():
            sock.close()
            raise MomlocError("the HTTP server did not start")
        time.sleep(0.02)
    return BackgroundServer(daemon, sock.getsockname()[1], server, thread, sock)
