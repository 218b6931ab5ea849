"""Issue 25, item 5: names, bodies and methods as a careless client sends them, against the real
daemon on loopback. Each test sends the exact request the probe found mishandled."""

from __future__ import annotations

import httpx
import pytest

from tests.e2e.server import running_server

pytestmark = pytest.mark.timeout(180)
JSON = {"Content-Type": "application/json"}
ONE_MARK = [{"name": "A", "x": 1.0, "y": 1.0}]


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with running_server() as srv:
        srv.setup.data_dir = tmp_path_factory.mktemp("setup")
        srv.wait_for_seq(3)
        yield srv


def post(server, path: str, body=None, **kw) -> httpx.Response:
    return httpx.post(server.http + path, json=body, timeout=30, **kw)


@pytest.mark.parametrize("name", ["zz.npz\n", "zz.npz\r", "a/zz.npz", ".npz", "zz.npz.tmp"])
def test_a_recording_name_that_is_not_a_plain_file_name_is_422(server, name):
    start = post(server, "/v1/setup/start", {"marks": ONE_MARK, "seconds": 1, "out": name})
    assert start.status_code == 422 and start.json()["detail"].startswith("body.out"), start.text
    train = post(server, "/v1/setup/train", {"recording": name})
    assert train.status_code == 422, train.text
    assert train.json()["detail"].startswith("body.recording"), train.text
    assert list(server.setup.data_dir.iterdir()) == []  # no file, newline or not
    assert server.setup.status()["state"] == "idle"


def test_a_chunked_body_over_1_mib_is_413(server):
    def chunks():  # no Content-Length: the guard can only count while reading
        yield b'{"model_dir": "'
        for _ in range(1100):
            yield b"x" * 1024
        yield b'"}'

    response = httpx.post(
        server.http + "/v1/model/reload", content=chunks(), headers=JSON, timeout=30
    )
    assert response.status_code == 413, response.text
    assert "larger than 1048576 bytes" in response.json()["detail"]
    small = httpx.post(  # chunked under the limit still reaches the route
        server.http + "/v1/model/reload", content=iter([b"{", b"}"]), headers=JSON, timeout=30
    )
    assert small.status_code == 200, small.text


@pytest.mark.parametrize(
    ("method", "path"),
    [("PUT", "/v1/positions"), ("DELETE", "/v1/health"), ("PATCH", "/v1/setup/status"),
     ("PUT", "/v1/setup/start"), ("DELETE", "/v1/model/reload")],
)  # fmt: skip
def test_a_method_the_route_does_not_have_is_405(server, method, path):
    for headers in ({}, JSON):  # with or without a JSON body: the method is what is wrong
        response = httpx.request(method, server.http + path, headers=headers, timeout=30)
        assert response.status_code == 405, (method, path, response.text)
        assert response.headers["allow"], response.headers
    assert httpx.request("PUT", server.http + "/v1/nothing-here", timeout=30).status_code == 404


@pytest.mark.parametrize(
    ("path", "field", "value"),
    [("/v1/setup/start", "seconds", True), ("/v1/setup/start", "seconds", "5"),
     ("/v1/setup/start", "walk", "yes"), ("/v1/setup/start", "countdown", False),
     ("/v1/setup/verify", "seconds", "5"), ("/v1/setup/train", "epochs", "5"),
     ("/v1/setup/train", "epochs", True), ("/v1/setup/train", "first_model", 1)],
)  # fmt: skip
def test_a_number_or_flag_of_another_type_is_422_naming_the_field(server, path, field, value):
    body = {field: value}
    if path == "/v1/setup/start":
        body |= {"marks": ONE_MARK, "out": "strict.npz"}
    response = post(server, path, body)
    assert response.status_code == 422, response.text
    assert response.json()["detail"].startswith(f"body.{field}:"), response.json()
    assert server.setup.status()["state"] == "idle"  # nothing started
    assert server.training.status()["state"] == "idle"


def test_every_post_declares_its_json_body_required_and_honours_it(server):
    spec = httpx.get(server.http + "/openapi.json", timeout=30).json()
    posts = {p: ops["post"] for p, ops in spec["paths"].items() if "post" in ops}
    assert "/v1/setup/train" in posts and "/v1/model/reload" in posts
    for path, operation in posts.items():
        assert operation["requestBody"]["required"] is True, path
        # a body-less POST may be a cross-site form: refused, as the schema now says
        assert httpx.post(server.http + path, timeout=30).status_code == 415, path
    assert post(server, "/v1/model/reload", {}).status_code == 200


def test_mqtt_discovery_remove_validates_its_body(server):
    for body in (b"[1, 2]", b'{"room": "x"}', b'"x"', b"null", b""):
        response = httpx.post(
            server.http + "/v1/mqtt/discovery/remove", content=body, headers=JSON, timeout=30
        )
        assert response.status_code == 422 and response.json()["detail"].startswith("body"), (
            body,
            response.text,
        )
    bad_utf8 = httpx.post(
        server.http + "/v1/mqtt/discovery/remove", content=b'{"\xff": 1}', headers=JSON, timeout=30
    )
    assert bad_utf8.status_code in (400, 422), bad_utf8.text
    assert set(bad_utf8.json()) == {"detail", "errors"}
    # a valid body reaches the route: no MQTT configured in this daemon
    assert post(server, "/v1/mqtt/discovery/remove", {}).status_code == 409


def test_every_4xx_a_body_route_can_answer_is_declared(server):
    spec = httpx.get(server.http + "/openapi.json", timeout=30).json()
    for path, operations in spec["paths"].items():
        for method, operation in operations.items():
            declared = set(operation["responses"])
            if "requestBody" in operation:
                assert {"400", "413", "415", "422"} <= declared, (method, path, declared)
