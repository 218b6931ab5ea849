"""Start the real daemon (uvicorn on a loopback port, in a thread) for end-to-end tests."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx

from service.daemon import Daemon, build_daemon, serve_in_thread
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


@contextmanager
def running_server(**settings: Any) -> Iterator[RunningServer]:
    """The demo daemon (synthetic scene, shipped model) on a free loopback port."""
    token = settings.pop("token", None)
    # The simulator's boxes unless a test asks for the drawn frames through the detector: these
    # tests are about the server, and the detector would only add CPU load and timing slack.
    settings.setdefault("detections", "simulated")
    model_dir = settings.pop("model_dir", None)
    config = demo_settings(host="127.0.0.1", **settings)
    if model_dir:
        config = config.model_copy(update={"model_dir": Path(model_dir)})
    daemon = build_daemon(config)
    daemon.token = token
    background = serve_in_thread(daemon)
    try:
        yield RunningServer(daemon, background.port, token)
    finally:
        background.stop()
