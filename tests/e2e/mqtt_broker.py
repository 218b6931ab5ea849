"""A real mosquitto broker on a free loopback port, and a real MQTT subscriber, for e2e tests.

``ensure_mosquitto`` installs Debian's ``mosquitto`` + ``mosquitto-clients`` once when missing
(the way ``tests/e2e/test_map_page.py`` installs chromium) and skips with the reason when that is
impossible. Each :class:`Broker` runs ``mosquitto -c`` with a temporary config: one listener on
127.0.0.1 only, anonymous access, no persistence (so a restart really forgets retained messages).
"""

from __future__ import annotations

import contextlib
import shutil
import socket
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from tests.e2e.debian import ensure_debian

MOSQUITTO = "/usr/sbin/mosquitto"


def ensure_mosquitto() -> str:
    """Path of the mosquitto binary, installing the Debian package if needed (else skip)."""
    found = shutil.which("mosquitto")
    if found:
        return found
    ensure_debian((MOSQUITTO,), ("mosquitto", "mosquitto-clients"), recommends=True)
    return MOSQUITTO


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def wait_port(port: int, timeout: float = 20.0) -> None:
    deadline = time.time() + timeout
    while True:
        with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), 0.5):
            return
        if time.time() > deadline:
            raise TimeoutError(f"nothing listens on 127.0.0.1:{port}")
        time.sleep(0.05)


class Broker:
    """One mosquitto process; ``stop`` / ``start`` again on the same port simulate a restart."""

    def __init__(self, binary: str, port: int | None = None) -> None:
        self.binary = binary
        self.port = port or free_port()
        self.dir = Path(tempfile.mkdtemp(prefix="momloc-mosquitto-"))
        self.dir.chmod(0o755)
        self.config = self.dir / "mosquitto.conf"
        self.config.write_text(
            f"listener {self.port} 127.0.0.1\n"
            "allow_anonymous true\n"
            "persistence false\n"
            "log_dest stderr\n"
            "log_type error\n"
            "log_type warning\n"
            "max_connections -1\n"
        )
        self.config.chmod(0o644)
        self.proc: subprocess.Popen | None = None
        self.log = self.dir / "mosquitto.log"

    def start(self) -> Broker:
        log = self.log.open("ab")
        self.proc = subprocess.Popen(
            [self.binary, "-c", str(self.config)], stdout=log, stderr=subprocess.STDOUT
        )
        try:
            wait_port(self.port)
        except TimeoutError:
            self.stop()
            raise RuntimeError(f"mosquitto did not start: {self.log.read_text()[-2000:]}") from None
        return self

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=10)
        self.proc = None

    def close(self) -> None:
        self.stop()
        shutil.rmtree(self.dir, ignore_errors=True)


@dataclass
class Message:
    topic: str
    payload: bytes
    retain: bool
    received: float  # wall clock, to compare with a snapshot's t

    @property
    def text(self) -> str:
        return self.payload.decode()


class Subscriber:
    """A real paho client that records every message on ``topics`` (its own network thread)."""

    def __init__(self, port: int, *topics: str, client_id: str | None = None) -> None:
        from paho.mqtt.client import CallbackAPIVersion, Client

        self.messages: list[Message] = []
        self._lock = threading.Lock()
        self._subscribed = threading.Event()
        self.topics = topics
        self.client = Client(CallbackAPIVersion.VERSION2, client_id=client_id or "")
        self.client.on_connect = self._on_connect
        self.client.on_message = self._on_message
        self.client.on_subscribe = lambda *a: self._subscribed.set()
        self.client.connect("127.0.0.1", port, keepalive=30)
        self.client.loop_start()
        if not self._subscribed.wait(20):
            raise TimeoutError("subscription not acknowledged")

    def _on_connect(self, client: Any, userdata: Any, flags: Any, reason: Any, props: Any) -> None:
        client.subscribe([(t, 1) for t in self.topics])

    def _on_message(self, client: Any, userdata: Any, msg: Any) -> None:
        with self._lock:
            self.messages.append(
                Message(msg.topic, bytes(msg.payload), bool(msg.retain), time.time())
            )

    def on(self, topic: str) -> list[Message]:
        with self._lock:
            return [m for m in self.messages if m.topic == topic]

    def wait_for(
        self, predicate: Callable[[Subscriber], Any], timeout: float = 60.0, what: str = "message"
    ) -> Any:
        deadline = time.time() + timeout
        while time.time() < deadline:
            value = predicate(self)
            if value:
                return value
            time.sleep(0.05)
        with self._lock:
            seen = sorted({m.topic for m in self.messages})
        raise AssertionError(f"timed out waiting for {what}; topics seen: {seen}")

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


class StallingProxy:
    """TCP proxy to a broker that can stop reading from the client (a broker that never reads).

    Broker -> client always flows (CONNACK arrives, the session looks healthy); after ``stall()``
    the proxy stops reading what the client sends, so the client's socket buffers fill up.
    """

    def __init__(self, target_port: int) -> None:
        self.target_port = target_port
        self.server = socket.socket()
        self.server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        # small buffers (set before accept, so the TCP window is small from the start): "never
        # reads" is then felt after kilobytes instead of the megabytes Linux buffers by default
        self.server.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        self.server.bind(("127.0.0.1", 0))
        self.server.listen(8)
        self.port = self.server.getsockname()[1]
        self.stalled = threading.Event()
        self.closed = threading.Event()
        self._threads: list[threading.Thread] = []
        self._sockets: list[socket.socket] = []
        self._spawn(self._accept)

    def _spawn(self, target: Callable[..., None], *args: Any) -> None:
        thread = threading.Thread(target=target, args=args, daemon=True)
        thread.start()
        self._threads.append(thread)

    def _accept(self) -> None:
        while not self.closed.is_set():
            try:
                client, _ = self.server.accept()
            except OSError:
                return
            upstream = socket.create_connection(("127.0.0.1", self.target_port))
            self._sockets += [client, upstream]
            self._spawn(self._pump, client, upstream, True)
            self._spawn(self._pump, upstream, client, False)

    def _pump(self, source: socket.socket, sink: socket.socket, from_client: bool) -> None:
        while not self.closed.is_set():
            if from_client and self.stalled.is_set():
                time.sleep(0.05)
                continue
            try:
                data = source.recv(4096)
                if not data:
                    return
                sink.sendall(data)
            except OSError:
                return

    def stall(self) -> None:
        self.stalled.set()

    def close(self) -> None:
        self.closed.set()
        for sock in [self.server, *self._sockets]:
            with contextlib.suppress(OSError):
                sock.close()


@pytest.fixture(scope="session")
def mosquitto() -> Any:
    """One broker for the test session (tests use distinct rooms, so they do not interfere)."""
    broker = Broker(ensure_mosquitto()).start()
    try:
        yield broker
    finally:
        broker.close()
