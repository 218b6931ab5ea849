"""Prometheus metrics, collected at scrape time from the pipeline, cameras and hub.

A private registry per daemon (not the process-global one) keeps several apps in one process
(tests, benchmarks) from clashing, and reading the live state at scrape time means the pipeline
thread does no metrics work per frame.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from prometheus_client import CONTENT_TYPE_LATEST, CollectorRegistry, generate_latest
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily
from prometheus_client.registry import Collector

from service.outputs.wiring import output_metrics


class _DaemonCollector(Collector):
    def __init__(self, daemon: Any) -> None:
        self.daemon = daemon

    def collect(self) -> Iterator[Any]:
        d = self.daemon
        stats = d.pipeline.stats()
        yield GaugeMetricFamily(
            "momloc_pipeline_fps", "Frame sets processed per second", stats["fps"]
        )
        lat = GaugeMetricFamily(
            "momloc_pipeline_latency_seconds",
            "Capture to publish latency over the last frames",
            labels=["quantile"],
        )
        for q in ("p50", "p95"):
            value = stats["latency_ms"][q]
            if value is not None:
                lat.add_metric([q.removeprefix("p")], value / 1e3)
        yield lat
        stage = GaugeMetricFamily(
            "momloc_stage_seconds", "Duration of the last run of each stage", labels=["stage"]
        )
        for name, ms in stats["stage_ms"].items():
            stage.add_metric([name], ms / 1e3)
        yield stage
        yield CounterMetricFamily(
            "momloc_frames_processed", "Frame sets processed", stats["frames_processed"]
        )
        yield CounterMetricFamily(
            "momloc_frames_dropped",
            "Frames skipped because the pipeline was busy",
            stats["frames_dropped"],
        )
        snapshot = d.hub.latest()
        yield GaugeMetricFamily(
            "momloc_people", "People in the newest snapshot", len(snapshot.people)
        )
        yield GaugeMetricFamily(
            "momloc_stream_clients", "Connected WebSocket clients", d.hub.subscriber_count
        )
        stream = d.hub.stream_stats()
        yield CounterMetricFamily("momloc_stream_sent", "Snapshots sent to clients", stream["sent"])
        yield CounterMetricFamily(
            "momloc_stream_sent_behind",
            "Snapshots sent while 2+ newer ones existed (event loop falling behind)",
            stream["sent_behind"],
        )
        yield GaugeMetricFamily(
            "momloc_model_loaded",
            "1 when a MoM model is loaded",
            int(d.pipeline.runtime is not None),
        )
        connected = GaugeMetricFamily(
            "momloc_camera_connected", "1 when the camera delivers frames", labels=["camera"]
        )
        fps = GaugeMetricFamily("momloc_camera_fps", "Camera frame rate", labels=["camera"])
        age = GaugeMetricFamily(
            "momloc_camera_frame_age_seconds", "Age of the newest frame", labels=["camera"]
        )
        for k, state in enumerate(d.camera_states()):
            connected.add_metric([str(k)], int(bool(state["connected"])))
            fps.add_metric([str(k)], float(state["fps"] or 0.0))
            if state["last_frame_age"] is not None:
                age.add_metric([str(k)], float(state["last_frame_age"]))
        yield connected
        yield fps
        yield age
        yield from output_metrics(d.outputs)  # zones and MQTT (service.outputs.wiring)


def metrics_text(daemon: Any) -> tuple[bytes, str]:
    """Prometheus exposition text and its content type."""
    registry = getattr(daemon, "_metrics_registry", None)
    if registry is None:
        registry = CollectorRegistry(auto_describe=False)
        registry.register(_DaemonCollector(daemon))
        daemon._metrics_registry = registry
    return generate_latest(registry), CONTENT_TYPE_LATEST
