"""Issue 12: bad input gets a clear 4xx naming the field, no page of another origin can use the
daemon, and no request can keep SIGTERM from stopping it. Each test sends the exact bad input."""

from __future__ import annotations

import asyncio
import json
import logging
import shutil
import time
from typing import Any

import httpx
import pytest
import websockets
from websockets.asyncio.client import connect

from service.settings import DEMO_MODEL_DIR
from service.setup import marks as marks_module
from service.setup.marks import FloorMark
from tests.e2e.server import running_server

pytestmark = pytest.mark.timeout(180)
EVIL = "http://evil.example"
JSON = {"Content-Type": "application/json"}


@pytest.fixture(scope="module")
def server():
    with running_server(allowed_origins=["http://localhost:3000"]) as srv:
        srv.wait_for_seq(3)
        yield srv


def post(server, path: str, content: str | None = None, **headers: str) -> httpx.Response:
    return httpx.post(server.http + path, content=content, headers={**JSON, **headers}, timeout=30)


async def handshake(url: str, **kw) -> int | str:
    """HTTP status of a refused handshake, or the close code, or "open" when a snapshot came."""
    try:
        async with connect(url, **kw) as ws:
            try:
                await asyncio.wait_for(ws.recv(), 10)
            except websockets.exceptions.ConnectionClosed as closed:
                assert closed.rcvd is not None
                return closed.rcvd.code
            return "open"
    except websockets.exceptions.InvalidStatus as refused:
        return refused.response.status_code


# -- 9: Origin and Host -------------------------------------------------------------------------


def test_websocket_from_a_foreign_origin_is_refused_before_accept(server):
    assert asyncio.run(handshake(server.ws + "/v1/stream", origin=EVIL)) == 403
    assert asyncio.run(handshake(server.ws + "/v1/stream", origin="null")) == 403
    own = f"http://127.0.0.1:{server.port}"
    assert asyncio.run(handshake(server.ws + "/v1/stream", origin=own)) == "open"
    listed = "http://localhost:3000"  # allowed_origins
    assert asyncio.run(handshake(server.ws + "/v1/stream", origin=listed)) == "open"
    assert asyncio.run(handshake(server.ws + "/v1/stream")) == "open"  # no Origin: not a page


@pytest.mark.parametrize("path", ["/v1/alignment/reset", "/v1/setup/stop", "/v1/model/reload"])
def test_state_changing_requests_from_a_foreign_page_are_403(server, path):
    refused = post(server, path, "{}", Origin=EVIL)
    assert refused.status_code == 403 and "origin" in refused.json()["detail"]
    # a cross-site HTML form can only send simple content types: refused too, with no Origin
    form = httpx.post(
        server.http + path, content="a=b", headers={"Content-Type": "text/plain"}, timeout=30
    )
    assert form.status_code == 415 and "JSON body" in form.json()["detail"]
    assert httpx.post(server.http + path, timeout=30).status_code == 415  # body-less POST


def test_reads_from_a_foreign_page_are_403_and_scripts_pass(server):
    assert server.get("/v1/positions", headers={"Origin": EVIL}).status_code == 403
    assert server.get("/v1/positions").status_code == 200  # curl, Python, game engines
    assert post(server, "/v1/alignment/reset", "{}").status_code == 200


def test_host_header_is_checked_against_dns_rebinding(server):
    rebound = server.get("/v1/positions", headers={"Host": f"evil.example:{server.port}"})
    assert rebound.status_code == 403 and "allowed_hosts" in rebound.json()["detail"]
    # the rebound page is same-origin with itself, so Origin alone would not stop it
    same = {"Host": f"evil.example:{server.port}", "Origin": f"http://evil.example:{server.port}"}
    assert server.get("/v1/positions", headers=same).status_code == 403
    for host in (f"localhost:{server.port}", f"127.0.0.1:{server.port}", f"[::1]:{server.port}"):
        assert server.get("/v1/positions", headers={"Host": host}).status_code == 200, host


def test_allowed_hosts_setting_admits_a_name():
    with running_server(allowed_hosts=["tracker.lan"]) as srv:
        srv.wait_for_seq(1)
        ok = srv.get("/v1/health", headers={"Host": f"tracker.lan:{srv.port}"})
        assert ok.status_code == 200
        assert srv.get("/v1/health", headers={"Host": "other.lan"}).status_code == 403


# -- 2, 3: model reload -------------------------------------------------------------------------


def test_overlong_model_dir_is_4xx_and_not_echoed(server, caplog):
    caplog.set_level(logging.INFO)
    logging.getLogger("uvicorn").addHandler(caplog.handler)
    current = server.daemon.pipeline.runtime
    too_long = post(server, "/v1/model/reload", json.dumps({"model_dir": "x" * 300}))
    assert too_long.status_code == 409, too_long.text
    assert "not a model directory" in too_long.json()["detail"]
    assert len(too_long.text) < 600
    huge = post(server, "/v1/model/reload", json.dumps({"model_dir": "/" + "y" * 10_000_000}))
    assert huge.status_code == 413
    over_limit = post(server, "/v1/model/reload", json.dumps({"model_dir": "z" * 5000}))
    assert over_limit.status_code == 422 and "model_dir" in over_limit.json()["detail"]
    assert len(over_limit.text) < 1000  # the 5000 characters are not echoed back
    logging.getLogger("uvicorn").removeHandler(caplog.handler)
    assert max((len(r.getMessage()) for r in caplog.records), default=0) < 2000
    assert not [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert server.daemon.pipeline.runtime is current


def test_reload_does_not_reveal_which_paths_exist(server, tmp_path):
    (tmp_path / "file.txt").write_text("x")
    answers = []
    for path in (tmp_path / "missing", tmp_path / "file.txt", tmp_path):
        response = post(server, "/v1/model/reload", json.dumps({"model_dir": str(path)}))
        assert response.status_code == 409
        answers.append(response.json()["detail"].removeprefix(str(path)))
    assert answers == [": not a model directory (no model.json)"] * 3


def test_model_json_with_a_wrong_type_is_409_naming_the_key(server, tmp_path):
    current = server.daemon.pipeline.runtime
    shutil.copy(DEMO_MODEL_DIR / "encoder.onnx", tmp_path / "encoder.onnx")
    meta = json.loads((DEMO_MODEL_DIR / "model.json").read_text())
    meta["encoder"] = "x"
    (tmp_path / "model.json").write_text(json.dumps(meta))
    response = post(server, "/v1/model/reload", json.dumps({"model_dir": str(tmp_path)}))
    assert response.status_code == 409, response.text
    assert "model.json: encoder:" in response.json()["detail"]
    assert server.daemon.pipeline.runtime is current


# -- 1, 4, 6: setup start -----------------------------------------------------------------------


def test_too_many_grid_marks_are_refused_at_once(server, monkeypatch):
    made: list[object] = []  # the refusal comes before a single mark is made (it took ~95 s)

    def counted(*a: Any) -> FloorMark:
        made.append(a)
        return FloorMark(*a)

    monkeypatch.setattr(marks_module, "FloorMark", counted)
    response = post(server, "/v1/setup/start", json.dumps({"grid": "1x20000", "room": "4x4"}))
    assert response.status_code == 422 and "at most 400" in response.json()["detail"]
    assert made == []
    marks = [{"name": f"m{i}", "x": i % 10, "y": i // 10 % 10} for i in range(401)]
    many = post(server, "/v1/setup/start", json.dumps({"marks": marks}))
    assert many.status_code == 422 and "marks" in many.json()["detail"]


@pytest.mark.parametrize("room", ["...x4", "4x...", ".x.", "1e3x4", "-4x4", "4x4x4"])
def test_malformed_room_is_422(server, room):
    response = post(server, "/v1/setup/start", json.dumps({"grid": "3x3", "room": room}))
    assert response.status_code == 422, response.text
    assert "room" in response.json()["detail"]


@pytest.mark.parametrize(
    ("marks", "named"),
    [
        ('[{"name": "A1", "x": NaN, "y": 1}]', "marks.0.x"),
        ('[{"name": "A1", "x": 1, "y": Infinity}]', "marks.0.y"),
        ('[{"name": "A1", "x": -Infinity, "y": 1}]', "marks.0.x"),
        ('[{"name": "A1", "x": 1e308, "y": 1}]', "marks.0.x"),
        ('[{"name": "A1", "x": false, "y": 1}]', "marks.0.x"),
        ('[{"name": "A1", "x": "1", "y": 1}]', "marks.0.x"),
        ('[{"name": "A1", "x": 1, "y": 1}, {"name": "A1", "x": 2, "y": 1}]', "'A1'"),
    ],
)
def test_bad_marks_are_422_naming_the_mark(server, tmp_path, marks, named):
    server.setup.data_dir = tmp_path
    response = post(server, "/v1/setup/start", f'{{"marks": {marks}, "seconds": 1}}')
    assert response.status_code == 422, response.text
    body = response.json()
    assert named in body["detail"], body
    assert server.setup.status()["state"] != "running"


# -- 8: bad ?rate= ------------------------------------------------------------------------------


def test_bad_rate_is_refused_without_an_error_log(server, caplog):
    uvicorn_log = logging.getLogger("uvicorn")  # does not propagate to the root logger
    uvicorn_log.addHandler(caplog.handler)
    try:
        for query in ("rate=abc", "rate=-1", "rate=nan", "rate=1e999"):
            assert asyncio.run(handshake(server.ws + f"/v1/stream?{query}")) == 4400, query
        time.sleep(0.2)
    finally:
        uvicorn_log.removeHandler(caplog.handler)
    errors = [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert not errors, [r.getMessage() for r in errors]


def test_token_is_checked_before_rate():
    with running_server(token="s3cret") as srv:
        srv.wait_for_seq(1)
        assert asyncio.run(handshake(srv.ws + "/v1/stream?rate=abc")) == 4401
        assert asyncio.run(handshake(srv.ws + "/v1/stream?rate=abc&token=s3cret")) == 4400
        assert httpx.get(srv.http + "/v1/settings/schema").status_code == 401  # every /v1 route


# -- 10: OpenAPI tells the truth ----------------------------------------------------------------


def test_openapi_documents_every_error_with_one_model(server):
    spec = server.get("/openapi.json").json()
    ref = "#/components/schemas/ErrorBody"
    for path, methods in spec["paths"].items():
        for method, operation in methods.items():
            for status, response in operation["responses"].items():
                if status.startswith(("4", "5")):
                    schema = response["content"]["application/json"]["schema"]
                    assert schema == {"$ref": ref}, (path, method, status)
            if path.startswith("/v1") or path == "/metrics":
                assert "401" in operation["responses"], (path, method)
    assert list(spec["paths"]["/metrics"]["get"]["responses"]["200"]["content"]) == ["text/plain"]
    reload_responses = spec["paths"]["/v1/model/reload"]["post"]["responses"]
    assert {"409", "413", "415", "422"} <= set(reload_responses)
    snapshot = spec["paths"]["/v1/cameras/{k}/snapshot.jpg"]["get"]["responses"]
    assert {"404", "422", "503"} <= set(snapshot)
    # the daemon's own 422 has the documented shape, like FastAPI's
    own = post(server, "/v1/setup/start", json.dumps({"grid": "3x3", "room": "...x4"}))
    framework = server.get("/v1/cameras/0/snapshot.jpg?quality=high")
    for response in (own, framework):
        body = response.json()
        assert response.status_code == 422 and isinstance(body["detail"], str), body
        assert isinstance(body["errors"], list)
    assert framework.json()["errors"][0]["loc"] == ["query", "quality"]
