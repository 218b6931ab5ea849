"""Pieces of the API that need no server: rate parsing, preview drawing, metrics text."""

from __future__ import annotations

from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from service.api.metrics import metrics_text
from service.api.routes.stream import _parse_rate
from service.api.snapshot_image import id_colour, render_camera_jpeg
from service.pipeline.hub import Hub
from service.pipeline.listeners import CameraView
from service.snapshot import EMPTY, Snapshot
from service.stages import FrameResult, FrameSet
from tests.people import person


@pytest.mark.parametrize(
    ("raw", "expected"),
    [
        (None, 30.0),
        ("10", 10.0),
        ("2.5", 2.5),
        ("1000", 30.0),
        ("0", None),
        ("-1", None),
        ("abc", None),
        ("nan", None),
        ("inf", None),
        ("", None),
    ],
)
def test_parse_rate(raw, expected):
    assert _parse_rate(raw, 30.0) == expected


def test_preview_draws_boxes_in_the_id_colour():
    image = np.full((120, 160, 3), 255, np.uint8)
    view = CameraView(
        image,
        [(np.array([20, 30, 80, 110], np.float32), 4), (np.array([np.nan] * 4, np.float32), None)],
    )
    data = render_camera_jpeg(view, quality=95)
    assert data is not None
    decoded = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    assert decoded is not None
    edge = decoded[70, 20].astype(int)  # left edge of the box, below the label
    assert np.abs(edge - np.array(id_colour(4))).max() < 40
    assert decoded[70, 50].min() > 230  # inside the box stays white
    assert image.min() == 255  # the pipeline's frame is never drawn on
    small = render_camera_jpeg(view, width=80)
    assert small is not None
    shrunk = cv2.imdecode(np.frombuffer(small, np.uint8), cv2.IMREAD_COLOR)
    assert shrunk is not None and shrunk.shape == (60, 80, 3)
    assert render_camera_jpeg(CameraView(None)) is None


def test_metrics_text_reads_live_state():
    hub = Hub()
    hub.publish(Snapshot.build(3, 1.0, [person(1), person(2)]))
    pipeline = SimpleNamespace(
        stats=lambda: {
            "fps": 29.5,
            "latency_ms": {"p50": 20.0, "p95": 35.0},
            "stage_ms": {"detect": 21.0},
            "frames_processed": 100,
            "frames_dropped": 4,
        },
        runtime=object(),
    )
    states = [{"connected": True, "fps": 30.0, "last_frame_age": 0.01}]
    daemon = SimpleNamespace(pipeline=pipeline, hub=hub, camera_states=lambda: states, outputs=None)
    body, content_type = metrics_text(daemon)
    text = body.decode()
    assert content_type.startswith("text/plain")
    assert "momloc_pipeline_fps 29.5" in text
    assert 'momloc_pipeline_latency_seconds{quantile="95"} 0.035' in text
    assert "momloc_people 2.0" in text
    assert 'momloc_camera_connected{camera="0"} 1.0' in text
    assert "momloc_frames_dropped_total 4.0" in text


def test_throughput_stats_are_read_safely_while_frames_are_published():
    """/v1/health read the fps window while the pipeline thread appended to it: CI saw
    'RuntimeError: deque mutated during iteration' (a 500). Here the publisher is let in
    exactly while stats() iterates the window; readers and the writer now share a lock, so it
    waits instead of mutating."""
    import threading
    from collections import deque

    from service.pipeline.listeners import Throughput

    reading, appended = threading.Event(), threading.Event()

    class Window(deque):
        def __iter__(self):
            iterator = super().__iter__()
            reading.set()
            appended.wait(0.5)  # a publisher that can get in appends now
            return iterator

    throughput = Throughput()
    frame = FrameResult(
        frame_set=FrameSet(frames=[], skew=0.0),
        t_capture=0.0,
        fused=[],
        detections=[],
        associations=[],
        tracks=[],
        snapshot=EMPTY,
        runtime=None,
        timings_ms={"detect": 1.0},
    )
    throughput(frame)
    throughput._done = Window(throughput._done, maxlen=120)

    def publish() -> None:
        reading.wait(5)
        throughput(frame)
        appended.set()

    publisher = threading.Thread(target=publish)
    publisher.start()
    stats = throughput.stats()
    publisher.join()
    assert appended.is_set() and stats["latency_ms"]["p50"] is not None
