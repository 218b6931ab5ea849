"""End to end: the real daemon on loopback (synthetic scene, shipped model, real association and
tracking), real HTTP and WebSocket clients."""

from __future__ import annotations

import asyncio
import itertools
import json
import shutil
import time

import cv2
import numpy as np
import pytest
import websockets
from websockets.asyncio.client import connect

from capture.synthetic import SyntheticRig
from models.simulate.scene import Scene
from service.settings import DEMO_MODEL_DIR
from service.snapshot import Person
from tests.e2e.client_checks import WIRE, Tap
from tests.e2e.server import match_to_truth, running_server

pytestmark = pytest.mark.timeout(180)
LAST_SEQ = 330


@pytest.fixture(scope="module")
def server():
    with running_server() as srv:
        srv.wait_for_seq(5)
        yield srv


async def receive(url: str, count: int, **kw) -> list[dict]:
    async with connect(url, **kw) as ws:
        return [json.loads(await asyncio.wait_for(ws.recv(), 10)) for _ in range(count)]


def test_stream_seq_increases_and_matches_snapshot_schema(server):
    messages = asyncio.run(receive(server.ws + "/v1/stream", 40))
    seqs = [m["seq"] for m in messages]
    assert all(b > a for a, b in itertools.pairwise(seqs)), seqs
    times = [m["t"] for m in messages]
    assert all(b > a for a, b in itertools.pairwise(times))
    for m in messages:
        WIRE.validate_python(m)  # the types of service.snapshot, no other field
        assert m["v"] == 1 and set(m) == {"v", "seq", "t", "people"}
        for p in m["people"]:
            # posture fields are sent only when they apply (the demo model has a height model)
            assert set(p) - {"outside", "posture", "posture_confidence"} == {
                "id",
                "x",
                "y",
                "vx",
                "vy",
                "confidence",
                "cameras",
            }
            assert ("posture" in p) == ("posture_confidence" in p)
            assert 0.0 <= p["confidence"] <= 1.0 and set(p["cameras"]) <= {0, 1}
    # t is wall-clock capture time (a monotonic one would be seconds since boot): since the
    # daemon started, never in the future; no bound on the delay, which a loaded machine sets
    assert server.daemon.started - 1.0 <= messages[0]["t"] <= messages[-1]["t"] <= time.time()


def test_positions_follow_ground_truth():
    """Every streamed person is matched to a simulated person; errors are model-sized.

    Deterministic: a lock-step rig (every scene frame processed, scene time) and a fixed window
    of snapshots (seq 31-330, recorded by a hub tap from the first one), so a loaded machine gets
    the very same figures; the WebSocket stream is checked to carry those same snapshots.
    """
    tap = Tap()
    with running_server(lockstep=True, publishers=[tap]) as server:
        server.wait_for_seq(LAST_SEQ)
        streamed = asyncio.run(receive(server.ws + "/v1/stream", 20))
        rig = server.daemon.pipeline.rig
    for m in streamed:
        assert m == tap.by_seq[m["seq"]].as_dict()  # what clients get is what was published
    window = [tap.by_seq[seq].as_dict() for seq in range(31, LAST_SEQ + 1)]  # tracks confirmed
    errors, reported, visible = match_to_truth(rig, window)
    assert visible > 0 and reported >= 0.8 * visible, (reported, visible)
    # The demo's default detector profile is the measured nanodet one (the replay gate of the
    # whole scene is tests/service/test_demo_accuracy.py). This window is deterministic;
    # measured 2026-12-02 with the daemon's tracker (covariances, coverage, RECOMMENDED): median
    # 0.231 m, 70.4 % within 0.5 m, 1092 people reported for 726 visible (tracks on lasting
    # false boxes). Gated at those figures with a small margin: a change of the chain that moves
    # them is a change to look at, not noise.
    assert np.median(errors) < 0.24, np.median(errors)
    assert np.mean(errors < 0.5) > 0.69, np.mean(errors < 0.5)


def test_positions_endpoint_and_rate_limit(server):
    body = server.get("/v1/positions").json()
    assert body["v"] == 1 and body["seq"] >= 5
    published_before = server.daemon.hub.published
    started = time.monotonic()
    slow = asyncio.run(receive(server.ws + "/v1/stream?rate=5", 6))
    elapsed = time.monotonic() - started
    published = server.daemon.hub.published - published_before
    # At most 5/s with a bucket of two: six messages span at least four intervals, whatever
    # the machine's load (a slow machine only makes the span longer).
    assert elapsed >= 0.95 * 4 / 5, elapsed
    # The client gets the newest snapshot, not a queue: the seqs it skips are the ones the
    # pipeline published meanwhile (about 30/s on an idle machine, fewer under load).
    gaps = np.diff([m["seq"] for m in slow])
    assert gaps.sum() >= 0.5 * (published - 2 * len(slow)), (gaps, published)


def test_stalled_client_does_not_stop_others(server):
    async def scenario() -> list[dict]:
        # max_queue=1 and tiny buffers: this client stops reading after one message
        stalled = await connect(server.ws + "/v1/stream", max_queue=1, ping_interval=None)
        try:
            await asyncio.sleep(1.0)
            fresh = await receive(server.ws + "/v1/stream", 60)
        finally:
            stalled.transport.abort()
        return fresh

    fresh = asyncio.run(scenario())
    seqs = [m["seq"] for m in fresh]
    assert seqs[-1] - seqs[0] >= 59 and all(b > a for a, b in itertools.pairwise(seqs))


def test_health_fields(server):
    health = server.get("/v1/health").json()
    assert health["status"] == "ok", health
    assert {"uptime_s", "cameras", "model", "pipeline", "clients"} <= set(health)
    assert len(health["cameras"]) == 2
    for cam in health["cameras"]:
        assert cam["connected"] is True and cam["fps"] > 0 and cam["last_frame_age"] < 2
        assert set(cam) >= {"index", "name", "connected", "fps", "last_frame_age", "reconnects"}
    assert health["model"]["loaded"] and health["model"]["num_cameras"] == 2
    assert health["model"]["compatible"] is True
    pipe = health["pipeline"]
    assert pipe["running"] and pipe["fps"] > 0 and pipe["latency_ms"]["p95"] is not None
    assert pipe["error"] is None


async def closed_code(url: str, **kw) -> int:
    """The close code of a stream the daemon accepts and then closes at once."""
    async with connect(url, **kw) as ws:
        with pytest.raises(websockets.exceptions.ConnectionClosed) as info:
            await asyncio.wait_for(ws.recv(), 10)
        assert info.value.rcvd is not None
        return info.value.rcvd.code


def test_malformed_query_parameters_are_4xx(server):
    for query in ("rate=abc", "rate=-2", "rate=0", "rate=nan"):
        assert asyncio.run(closed_code(server.ws + f"/v1/stream?{query}")) == 4400, query
    assert server.get("/v1/cameras/abc/snapshot.jpg").status_code == 422
    assert server.get("/v1/cameras/0/snapshot.jpg?quality=high").status_code == 422
    assert server.get("/v1/cameras/0/snapshot.jpg?width=-5").status_code == 422
    assert server.get("/v1/cameras/7/snapshot.jpg").status_code == 404


def test_camera_snapshot_and_metrics(server):
    response = server.get("/v1/cameras/1/snapshot.jpg?width=320")
    if response.status_code == 503:
        pytest.skip("simulator renders no frames in this build")
    assert response.headers["content-type"] == "image/jpeg"
    image = cv2.imdecode(np.frombuffer(response.content, np.uint8), cv2.IMREAD_COLOR)
    assert image is not None and image.shape == (240, 320, 3)
    metrics = server.get("/metrics").text
    for name in ("momloc_pipeline_fps", "momloc_camera_connected", "momloc_stream_clients"):
        assert name in metrics


def test_model_reload_endpoint(server, tmp_path):
    ok = httpx_post(server, "/v1/model/reload", {})
    assert ok.status_code == 200 and ok.json()["loaded"]
    bad = httpx_post(server, "/v1/model/reload", {"model_dir": str(tmp_path)})
    assert bad.status_code == 409 and "model.json" in bad.json()["detail"]
    # a real model trained for other image sizes is refused and the running one stays
    current = server.daemon.pipeline.runtime
    other = tmp_path / "hd_model"
    other.mkdir()
    shutil.copy(DEMO_MODEL_DIR / "encoder.onnx", other / "encoder.onnx")
    meta = json.loads((DEMO_MODEL_DIR / "model.json").read_text())
    meta["image_sizes"] = [[1280, 720], [1280, 720]]
    (other / "model.json").write_text(json.dumps(meta))
    refused = httpx_post(server, "/v1/model/reload", {"model_dir": str(other)})
    assert refused.status_code == 409, refused.text
    assert (
        "1280x720" in refused.json()["detail"]
        and "keeping the current model" in refused.json()["detail"]
    )
    assert server.daemon.pipeline.runtime is current
    assert server.get("/v1/health").json()["model"]["loaded"]


def test_alignment_reset_endpoint(server):
    reset = httpx_post(server, "/v1/alignment/reset", {})
    assert reset.status_code == 200, reset.text
    cameras = reset.json()["cameras"]
    assert len(cameras) == 2 and not any(c["moved"] for c in cameras)


def httpx_post(server, path, body):
    import httpx

    return httpx.post(server.http + path, json=body, headers=server.headers(), timeout=30)


def test_openapi_docs(server):
    assert server.get("/docs").status_code == 200
    paths = server.get("/openapi.json").json()["paths"]
    assert {"/v1/positions", "/v1/health", "/v1/cameras/{k}/snapshot.jpg"} <= set(paths)
    schema = server.get("/v1/settings/schema").json()
    assert "description" in schema["properties"]["port"]


def test_openapi_declares_the_snapshot_and_its_person(server):
    """``/docs`` shows the wire format: ``/v1/positions`` answers a ``SnapshotBody`` whose
    people are ``Person`` objects with every field of ``service.snapshot.Person``."""
    spec = server.get("/openapi.json").json()
    answer = spec["paths"]["/v1/positions"]["get"]["responses"]["200"]["content"]
    assert answer["application/json"]["schema"] == {"$ref": "#/components/schemas/SnapshotBody"}
    schemas = spec["components"]["schemas"]
    body = schemas["SnapshotBody"]
    assert set(body["properties"]) == {"v", "seq", "t", "people"}
    assert body["properties"]["people"]["items"] == {"$ref": "#/components/schemas/Person"}
    person = schemas["Person"]
    fields = {"id", "x", "y", "vx", "vy", "confidence", "cameras"}
    optional = {"outside", "posture", "posture_confidence"}  # sent only when they apply
    assert set(person["properties"]) == fields | optional == set(Person.__annotations__)
    assert set(person["required"]) == fields
    assert person["additionalProperties"] is False
    assert all(person["properties"][name].get("description") for name in person["properties"])


def test_token_auth():
    with running_server(token="s3cret") as srv:
        srv.wait_for_seq(2)
        import httpx

        assert httpx.get(srv.http + "/v1/positions").status_code == 401
        assert httpx.get(srv.http + "/metrics").status_code == 401
        wrong = {"Authorization": "Bearer nope"}
        assert httpx.get(srv.http + "/v1/health", headers=wrong).status_code == 401
        assert srv.get("/v1/positions").status_code == 200
        assert httpx.get(srv.http + "/v1/positions?token=s3cret").status_code == 200
        assert httpx.get(srv.http + "/").status_code == 200  # the page itself carries no data

        assert asyncio.run(closed_code(srv.ws + "/v1/stream")) == 4401
        assert asyncio.run(closed_code(srv.ws + "/v1/stream?token=nope")) == 4401
        assert len(asyncio.run(receive(srv.ws + "/v1/stream?token=s3cret", 2))) == 2
        bearer = asyncio.run(receive(srv.ws + "/v1/stream", 2, additional_headers=srv.headers()))
        assert bearer[1]["seq"] > bearer[0]["seq"]


def test_rendered_frames_through_the_real_detector():
    """Drawn frames -> the real detector -> association -> MoM: found people are where they are.

    Lock-step rig: every scene frame is processed, with scene timestamps, so the accuracy is the
    same on an idle and on a loaded machine (paced in real time, a busy machine dropped frames
    and the check failed at 84.8 %). Each snapshot is compared with the ground truth of the very
    frame it was computed from.
    """
    with running_server(detections="rendered", lockstep=True) as srv:
        srv.wait_for_seq(20, timeout=120)
        rig = srv.daemon.pipeline.rig
        assert isinstance(rig, SyntheticRig) and isinstance(rig.scene, Scene)
        scene = rig.scene
        messages = asyncio.run(receive(srv.ws + "/v1/stream", 40, open_timeout=30))
        # Tracks coasting after a miss are still reported, with a confidence that falls towards 0
        # (the API's documented way to tell them apart); they drift, so the check is on people
        # reported with confidence >= 0.5. Measured 2026-12-01 (120 snapshots, NanoDet, the demo
        # model trained on its boxes): all reported 83.5 % within 1 m, confidence >= 0.5 99.2 %.
        errors = []
        for m in messages:
            truth = scene.observe(rig.index_at(m["t"])).world[:, :2]
            for p in m["people"]:
                if p["confidence"] >= 0.5:
                    errors.append(np.linalg.norm(truth - [p["x"], p["y"]], axis=1).min())
        assert len(errors) >= 20, "the detector found almost nobody in the drawn frames"
        assert np.median(errors) < 0.5 and np.mean(np.array(errors) < 1.0) > 0.9, errors
        health = srv.get("/v1/health").json()
        assert health["pipeline"]["stage_ms"]["detect"] > 0
        assert health["pipeline"]["frames_dropped"] == 0  # lock-step: nothing skipped
