"""Privacy mode through the real daemon: under ``MOMLOC_PRIVACY=positions_only`` no image bytes
leave the process, by any route, WebSocket, MQTT message, OSC datagram, log line or file.

The routes are not listed here: they are read from the running app (``app.routes``: API routes,
the static ``/web`` mount file by file, WebSockets, the docs pages), so a route added later is
called too. A path parameter this test does not know fails the test, asking for a value.

The converse runs the same harvest in normal mode and requires the scanner to find a JPEG in
exactly the camera snapshots: the scanner works, and nothing else carries an image in either mode.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import json
import logging
import re
import socket
import time
from pathlib import Path
from typing import Any

import httpx
import pytest
from starlette.routing import Mount, Route, WebSocketRoute
from websockets.asyncio.client import connect

from tests.e2e.mqtt_broker import Subscriber
from tests.e2e.server import RunningServer, running_server, wait_for

pytestmark = pytest.mark.timeout(400)
TOKEN = "privacy-token"
MAGIC = {"JPEG": b"\xff\xd8\xff", "PNG": b"\x89PNG\r\n\x1a\n"}


def signatures() -> dict[str, bytes]:
    """What an image looks like in a message: its magic bytes raw, in base64 (standard and
    URL-safe, as a data URI or a JSON field would carry a whole image), in hex, and as the
    escapes JSON writes for bytes decoded as Latin-1."""
    found = {}
    for kind, magic in MAGIC.items():
        encoded = base64.b64encode(magic)
        whole = encoded[: len(magic) * 8 // 6]  # the characters made of magic bits only
        found[kind] = magic
        found[f"{kind} base64"] = whole
        found[f"{kind} base64url"] = base64.urlsafe_b64encode(magic)[: len(whole)]
        found[f"{kind} hex"] = magic[:3].hex().encode()
        found[f"{kind} JSON escapes"] = json.dumps(magic[:4].decode("latin-1"))[1:-1].encode()
    return found


SIGNATURES = signatures()


def images_in(data: bytes) -> list[str]:
    """The kinds of image signature ``data`` contains (hex case-insensitively)."""
    lowered = data.lower()
    return [
        kind
        for kind, sig in SIGNATURES.items()
        if sig in data or (kind.endswith("hex") and sig in lowered)
    ]


def path_values(srv: RunningServer) -> dict[str, list[str]]:
    """A value for every path parameter the daemon's routes have (each camera, one beyond)."""
    cameras = len(srv.daemon.camera_names)
    return {"k": [str(k) for k in range(cameras + 1)]}


def leaf_routes(routes: list[Any], prefix: str = "") -> list[tuple[str, Any]]:
    """(full path, route) of every route under ``routes``, routers included by
    ``include_router`` opened (FastAPI keeps them as one entry holding the router)."""
    leaves = []
    for route in routes:
        included = getattr(route, "original_router", None)
        if included is not None:
            inner = prefix + getattr(getattr(route, "include_context", None), "prefix", "")
            leaves += leaf_routes(included.routes, inner)
        else:
            leaves.append((prefix + getattr(route, "path", ""), route))
    return leaves


def requests_of(srv: RunningServer) -> tuple[list[tuple[str, str]], list[str]]:
    """Every (method, path) the app serves and its WebSocket paths, read from the app itself;
    every path of ``/openapi.json`` must be among them (so a change in how the framework keeps
    its routes fails here instead of leaving routes out)."""
    values = path_values(srv)
    calls: list[tuple[str, str]] = []
    sockets: list[str] = []
    templates: set[str] = set()
    for template, route in leaf_routes(list(srv.app.routes)):
        if isinstance(route, Mount):  # static files: every one of them
            directory = Path(route.app.directory)  # type: ignore[attr-defined]
            calls += [
                ("GET", f"{template}/{f.relative_to(directory)}")
                for f in sorted(directory.rglob("*"))
                if f.is_file()
            ]
            continue
        templates.add(template)
        names = re.findall(r"{(\w+)(?::\w+)?}", template)
        unknown = set(names) - set(values)
        assert not unknown, f"{template}: give this test values for {unknown}"
        paths = [template]
        for name in names:
            pattern = "{" + name + r"(?::\w+)?}"
            paths = [re.sub(pattern, v, p) for p in paths for v in values[name]]
        if isinstance(route, WebSocketRoute):
            sockets += paths
            continue
        assert isinstance(route, Route), f"{template}: a route of a kind this test cannot call"
        methods = sorted(set(route.methods or {"GET"}) - {"HEAD"})
        calls += [(m, p) for m in methods for p in paths]
    documented = set(srv.get("/openapi.json").json()["paths"])
    assert documented <= templates, documented - templates
    return calls, sockets


async def websocket_messages(srv: RunningServer, paths: list[str]) -> dict[str, list[bytes]]:
    """Up to 30 messages (or 5 s of them) from each WebSocket route."""
    out: dict[str, list[bytes]] = {}
    for path in paths:
        got: list[bytes] = []
        async with connect(f"{srv.ws}{path}?token={TOKEN}") as ws:
            with contextlib.suppress(TimeoutError, Exception):
                deadline = time.monotonic() + 5
                while len(got) < 30 and time.monotonic() < deadline:
                    message = await asyncio.wait_for(ws.recv(), deadline - time.monotonic())
                    got.append(message if isinstance(message, bytes) else message.encode())
        out[path] = got
    return out


class LogTap(logging.Handler):
    """Every log record of the run, formatted as the daemon's log would show it."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.lines: list[str] = []
        self.setFormatter(logging.Formatter("%(name)s %(levelname)s %(message)s"))

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append(self.format(record))


def harvest(privacy: str, broker: Any, monkeypatch: Any, tmp_path: Path) -> dict[str, Any]:
    """Run the demo daemon as a user would (environment), call everything, collect every byte."""
    osc = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    osc.bind(("127.0.0.1", 0))
    osc.settimeout(0.2)
    monkeypatch.chdir(tmp_path)
    for key, value in {
        "MOMLOC_PRIVACY": privacy,
        "MOMLOC_DATA_DIR": str(tmp_path / "data"),
        "MOMLOC_OSC__PORT": str(osc.getsockname()[1]),
        "MOMLOC_MQTT__HOST": "127.0.0.1",
        "MOMLOC_MQTT__PORT": str(broker.port),
        "MOMLOC_MQTT__ROOM": f"privacy{privacy.replace('_', '')}",
    }.items():
        monkeypatch.setenv(key, value)
    logs, root = LogTap(), logging.getLogger()
    level = root.level
    root.addHandler(logs)
    root.setLevel(logging.DEBUG)  # every record any logger lets through
    subscriber = Subscriber(broker.port, "#")
    bodies: dict[tuple[str, str], httpx.Response] = {}
    try:
        with running_server(token=TOKEN, people=2) as srv:
            srv.wait_for_seq(5)
            # steady state: every camera has delivered a previewed frame
            for k in range(len(srv.daemon.camera_names)):
                wait_for(
                    lambda k=k: srv.get(f"/v1/cameras/{k}/boxes").json(),
                    lambda view: view["width"] is not None,
                    120,
                    f"camera {k} preview",
                )
            calls, sockets = requests_of(srv)
            for method, path in calls:
                body: dict[str, str] | None = {} if method in ("POST", "PUT", "PATCH") else None
                bodies[(method, path)] = httpx.request(
                    method, srv.http + path, headers=srv.headers(), json=body, timeout=30
                )
            streamed = asyncio.run(websocket_messages(srv, sockets))
            wait_for(
                lambda: [m for m in subscriber.messages if m.topic.endswith("/positions")],
                bool,
                60,
                "MQTT positions",
            )
            datagrams: list[bytes] = []
            with contextlib.suppress(TimeoutError):
                while len(datagrams) < 20:
                    datagrams.append(osc.recv(65536))
            health = srv.get("/v1/health").json()
    finally:
        root.removeHandler(logs)
        root.setLevel(level)
        subscriber.close()
        osc.close()
    files = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    return {
        "calls": calls,
        "bodies": bodies,
        "streamed": streamed,
        "mqtt": list(subscriber.messages),
        "osc": datagrams,
        "logs": logs.lines,
        "files": files,
        "health": health,
    }


def leaks(run: dict[str, Any]) -> dict[str, list[str]]:
    """Where an image signature showed up, and which."""
    found: dict[str, list[str]] = {}

    def check(where: str, data: bytes) -> None:
        kinds = images_in(data)
        if kinds:
            found[where] = kinds

    for (method, path), response in run["bodies"].items():
        check(f"{method} {path}", response.content)
        check(f"{method} {path} headers", str(response.headers).encode())
    for path, messages in run["streamed"].items():
        for i, message in enumerate(messages):
            check(f"WS {path} #{i}", message)
    for message in run["mqtt"]:
        check(f"MQTT {message.topic}", message.topic.encode() + message.payload)
    for i, datagram in enumerate(run["osc"]):
        check(f"OSC datagram {i}", datagram)
    check("log", "\n".join(run["logs"]).encode())
    for path, data in run["files"].items():
        check(f"file {path}", data)
    return found


def test_positions_only_lets_no_image_out(mosquitto, monkeypatch, tmp_path):
    run = harvest("positions_only", mosquitto, monkeypatch, tmp_path)
    assert leaks(run) == {}
    # everything was really exercised: routes, both WebSockets' stream, MQTT, OSC
    assert {p for _, p in run["calls"]} >= {"/v1/cameras/0/snapshot.jpg", "/v1/health", "/"}
    assert any(p.startswith("/web/") for _, p in run["calls"])
    assert len(run["streamed"]["/v1/stream"]) >= 10 and "/v1/events" in run["streamed"]
    assert {"/v1/setup/status", "/v1/zones"} <= {p for _, p in run["calls"]}
    assert run["mqtt"] and run["osc"] and run["logs"]
    # the snapshot says why it is refused, naming the setting; the boxes are there instead
    refused = run["bodies"][("GET", "/v1/cameras/0/snapshot.jpg")]
    assert refused.status_code == 403, refused.text
    assert "privacy" in refused.json()["detail"] and "MOMLOC_PRIVACY" in refused.json()["detail"]
    boxes = run["bodies"][("GET", "/v1/cameras/0/boxes")]
    assert boxes.status_code == 200 and boxes.json()["width"] == 640
    assert run["health"]["privacy"] == "positions_only"
    config = run["bodies"][("GET", "/v1/config")].json()
    assert config["privacy"] == "positions_only"
    assert all(r.status_code < 500 for r in run["bodies"].values())


def test_normal_mode_serves_images_and_the_scan_finds_exactly_them(
    mosquitto, monkeypatch, tmp_path
):
    """The converse: the scanner sees the snapshots' JPEGs (so it can fail), nothing else."""
    run = harvest("off", mosquitto, monkeypatch, tmp_path)
    cameras = len(run["health"]["cameras"])
    expected = {f"GET /v1/cameras/{k}/snapshot.jpg" for k in range(cameras)}
    found = leaks(run)
    assert set(found) == expected, found
    assert all("JPEG" in kinds for kinds in found.values())
    assert run["health"]["privacy"] == "off"
