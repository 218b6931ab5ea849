"""Issue 25, item 2: a hot reload cannot break serving, and a failing frame set does not flood
the log.

The real daemon on loopback (demo scene, shipped model). The bad model is the one a careless user
makes: the shipped detector's ONNX graph copied over ``encoder.onnx``. It loads (any ONNX file
does), has the right ``model.json``, and used to be answered 200 "compatible", after which every
frame set failed with one traceback each. ``MomRuntime.load`` now runs it once on the model's own
cameras; refused, the old model keeps serving.
"""

from __future__ import annotations

import logging
import os
import shutil
import time
from pathlib import Path

import httpx
import pytest

from service.settings import DEMO_MODEL_DIR
from tests.e2e.server import RunningServer, running_server

pytestmark = pytest.mark.timeout(180)
DETECTOR_GRAPH = Path(__file__).resolve().parents[2] / "models/detector/weights/nanodet_person.onnx"


def model_copy(folder: Path) -> Path:
    """The shipped demo model's two files in a folder of the test's own."""
    folder.mkdir()
    for name in ("encoder.onnx", "model.json"):
        shutil.copy(DEMO_MODEL_DIR / name, folder / name)
    return folder


def still_serving(server: RunningServer, model: Path) -> dict:
    """The pipeline goes on publishing positions from ``model``, without a failure."""
    seq = server.daemon.hub.latest().seq
    server.wait_for_seq(seq + 20)
    health = server.get("/v1/health").json()
    assert Path(health["model"]["path"]) == model and health["model"]["compatible"]
    assert health["pipeline"]["failures"] == 0 and health["pipeline"]["error"] is None, health
    deadline = time.time() + 30
    while not server.get("/v1/positions").json()["people"]:
        assert time.time() < deadline, "no positions served"
        time.sleep(0.1)
    return health


def test_reload_endpoint_refuses_a_graph_that_is_no_encoder(tmp_path):
    bad = model_copy(tmp_path / "bad")
    shutil.copy(DETECTOR_GRAPH, bad / "encoder.onnx")
    with running_server() as server:
        server.wait_for_seq(5)
        answer = httpx.post(
            server.http + "/v1/model/reload",
            json={"model_dir": str(bad)},
            headers=server.headers(),
            timeout=30,
        )
        assert answer.status_code == 409, answer.text
        detail = answer.json()["detail"]
        assert "encoder.onnx: does not run as this model's encoder" in detail, detail
        still_serving(server, DEMO_MODEL_DIR)


def test_watcher_keeps_the_served_model_when_its_encoder_is_overwritten(tmp_path):
    served = model_copy(tmp_path / "model")
    with running_server(model_dir=served) as server:
        server.wait_for_seq(5)
        swap = served / ".encoder.onnx.tmp"
        shutil.copy(DETECTOR_GRAPH, swap)
        os.replace(swap, served / "encoder.onnx")  # as a trainer writes it: one rename
        deadline = time.time() + 60  # the watcher polls every 2 s and waits one more poll
        while (reload := server.get("/v1/health").json()["model_reload"]) is None:
            assert time.time() < deadline, "the watcher did not act on the new encoder"
            time.sleep(0.2)
        assert reload["ok"] is False and "does not run" in reload["error"], reload
        still_serving(server, served)


def test_a_failing_frame_set_is_logged_once_then_counted(caplog):
    caplog.set_level(logging.INFO, logger="momloc.pipeline")
    with running_server() as server:
        pipeline = server.daemon.pipeline
        server.wait_for_seq(5)
        pipeline.failure_log.every_s = 1.0  # the count line every second instead of every minute

        def broken(*args, **kwargs):
            raise RuntimeError("association broke")

        working, pipeline.chain.associate = pipeline.chain.associate, broken
        began = time.monotonic()
        deadline = began + 60
        while pipeline.failures < 20 or time.monotonic() - began < 2.5:
            assert time.monotonic() < deadline, f"only {pipeline.failures} failures"
            time.sleep(0.05)
        pipeline.chain.associate = working
        failed_for = time.monotonic() - began
        server.wait_for_seq(server.daemon.hub.latest().seq + 5)
        failures = pipeline.failures

    records = [r for r in caplog.records if r.name == "momloc.pipeline"]
    tracebacks = [r for r in records if r.exc_info]
    assert len(tracebacks) == 1, f"{len(tracebacks)} tracebacks for {failures} failed frame sets"
    assert "RuntimeError" in tracebacks[0].getMessage()
    counts = [r.getMessage() for r in records if "frame sets failed since" in r.getMessage()]
    # one count line per second of failures at most, and at least one in 2.5 s
    assert 1 <= len(counts) <= failed_for + 1, counts
    assert "association broke" in counts[-1]
    again = [r.getMessage() for r in records if "work again" in r.getMessage()]
    assert again == [f"frame sets work again after {failures} failed since {again[0][-8:]}"]
