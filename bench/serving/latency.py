"""Service benchmark: capture -> WebSocket latency, pipeline fps, 200 clients, memory under churn.

Frames: a clip of the demo scene is drawn *before* timing starts and replayed at 30 fps by a rig
that behaves like two cameras (newest frame only, wall-clock capture timestamps), so the figures
measure the daemon (real SSDLite detector, shipped MoM model, association, tracking, hub,
uvicorn, WebSocket) and not the simulator's drawing. Clients run in a separate process (their
own interpreter, like real clients) and stamp every message on receipt; latency = receive time -
snapshot ``t`` (same host clock). A client's lag = snapshots published before it received one,
minus that one's ``seq``.

    .venv/bin/python -m bench.serving.latency [--seconds 20] [--memory-seconds 60] [--clients 200]

Writes bench/results/service_latency.md.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.report import write_report

RESULTS = Path(__file__).resolve().parents[1] / "results" / "service_latency.md"


def rss_mb() -> float:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


# -- server side -------------------------------------------------------------------------------


def start_daemon(detections: str, clip_frames: int, model_dir: Path | None) -> Any:
    from capture.synthetic import SyntheticRig
    from service.api.server import serve_in_thread
    from service.daemon import build_daemon
    from service.demo import demo_settings

    class LoopedScene:
        """Loops a pre-drawn clip of a scene: camera-like timing without the drawing cost."""

        def __init__(self, scene: Any, cameras: list[int]) -> None:
            self.scene, self.fps, self.num_cameras = scene, scene.fps, scene.num_cameras
            self.clip = {k: [scene.render(i, k) for i in range(clip_frames)] for k in cameras}

        def render(self, frame_index: int, camera_index: int) -> np.ndarray:
            return self.clip[camera_index][frame_index % clip_frames]

        def observe(self, frame_index: int) -> Any:
            return self.scene.observe(frame_index % clip_frames)

    settings = demo_settings(detections=detections)
    if model_dir is not None:
        settings = settings.model_copy(update={"model_dir": model_dir})
    daemon = build_daemon(settings)
    rig = daemon.pipeline.rig
    looped = LoopedScene(rig.scene, rig.cameras)
    daemon.pipeline.rig = SyntheticRig(looped, rig.cameras, fps=rig.fps, render_every=1)
    stage = daemon.pipeline.detect
    if hasattr(stage, "scene"):  # simulated detections: the looped clip's boxes
        stage.scene = looped
    publish_times: list[tuple[int, float]] = []
    original = daemon.hub.publish

    def recording_publish(snapshot: Any) -> None:
        original(snapshot)
        publish_times.append((snapshot.seq, time.time()))

    daemon.hub.publish = recording_publish  # type: ignore[method-assign]
    return serve_in_thread(daemon), publish_times


def fps_between(publish_times: list[tuple[int, float]], t0: float, t1: float) -> float:
    times = [t for _, t in publish_times if t0 <= t <= t1]
    return (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 else 0.0


def lag_in_snapshots(records: list[list[float]], publish_times: list[tuple[int, float]]) -> Any:
    """For each received (seq, t, recv): published-before-receipt seq minus received seq."""
    seqs = np.array([s for s, _ in publish_times], float)
    times = np.array([t for _, t in publish_times], float)
    out = []
    for seq, _t, recv in records:
        i = np.searchsorted(times, recv, side="right") - 1
        out.append(max(0.0, seqs[i] - seq) if i >= 0 else 0.0)
    return np.array(out)


def run_clients(
    url: str, clients: int, seconds: float, churn: float, out: Path, procs: int = 1
) -> None:
    """Run ``clients`` spread over ``procs`` client processes; merged records go to ``out``."""
    procs = max(1, min(procs, clients))
    running = []
    for i in range(procs):
        share = clients // procs + (1 if i < clients % procs else 0)
        part = out.with_suffix(f".{i}.json")
        cmd = [sys.executable, "-m", "bench.serving.latency", "--worker", url, str(share)]
        cmd += [str(seconds), str(churn / procs), str(part)]
        running.append((subprocess.Popen(cmd), part))
    records: list = []
    for proc, part in running:
        if proc.wait(timeout=seconds + 120) != 0:
            raise RuntimeError("a benchmark client process failed")
        records += json.loads(part.read_text())
        part.unlink()
    out.write_text(json.dumps(records))


# -- client side (separate process) ------------------------------------------------------------


async def _client(url: str, stop_at: float, records: list, keep: bool, cancel: asyncio.Event):
    import websockets

    async with websockets.connect(url, max_size=2**20) as ws:
        while time.time() < stop_at and not cancel.is_set():
            try:
                raw = await asyncio.wait_for(ws.recv(), timeout=1.0)
            except TimeoutError:
                continue
            now = time.time()
            if keep:  # the wire format starts {"v":1,"seq":N,"t":T,...: skip a full JSON parse
                head = raw[: raw.index(',"people"')] + "}"
                msg = json.loads(head)
                records.append([msg["seq"], msg["t"], now])


async def _workers(url: str, clients: int, seconds: float, churn: float) -> list:
    stop_at = time.time() + seconds
    records: list = []
    live: list[tuple[asyncio.Task, asyncio.Event]] = []

    def spawn(index: int) -> None:
        cancel = asyncio.Event()
        keep = index < 10 or churn == 0  # record a sample of clients; all read everything
        task = asyncio.create_task(_client(url, stop_at, records, keep, cancel))
        live.append((task, cancel))

    for i in range(clients):
        spawn(i)
        if i % 20 == 19:
            await asyncio.sleep(0.05)
    rng = random.Random(0)
    while time.time() < stop_at:
        await asyncio.sleep(1.0)
        if churn > 0:  # clients leave and others join
            leaving = rng.sample(range(len(live)), round(churn))
            for i in sorted(leaving, reverse=True):
                live.pop(i)[1].set()
            for _ in leaving:
                spawn(clients)
    await asyncio.gather(*(t for t, _ in live), return_exceptions=True)
    return records


def worker_main(url: str, clients: int, seconds: float, churn: float, out: Path) -> None:
    records = asyncio.run(_workers(url, clients, seconds, churn))
    out.write_text(json.dumps(records))


# -- scenarios ---------------------------------------------------------------------------------


def scenario(detections: str, args: argparse.Namespace) -> dict[str, Any]:
    background, publish = start_daemon(detections, args.clip, args.model)
    url = f"ws://127.0.0.1:{background.port}/v1/stream"
    out = Path(tempfile.mkstemp(suffix=".json")[1])
    try:
        time.sleep(3.0)  # warm-up: tracks confirmed, onnxruntime arenas allocated
        t0 = time.time()
        run_clients(url, 1, args.seconds, 0, out)
        one = np.array(json.loads(out.read_text()))
        fps_one = fps_between(publish, t0 + 1, time.time() - 1)
        stats_one = background.daemon.pipeline.stats()
        t1 = time.time()
        hub = background.daemon.hub
        before = hub.stream_stats()
        run_clients(url, args.clients, args.seconds, 0, out, args.client_procs)
        after = hub.stream_stats()
        many = np.array(json.loads(out.read_text()))
        fps_many = fps_between(publish, t1 + 3, time.time() - 1)
        lat_one = (one[:, 2] - one[:, 1]) * 1e3
        lat_many = (many[:, 2] - many[:, 1]) * 1e3
        lag = lag_in_snapshots(many.tolist(), publish)
        result = {
            "detections": detections,
            "latency_p50": float(np.percentile(lat_one, 50)),
            "latency_p95": float(np.percentile(lat_one, 95)),
            "fps": fps_one,
            "dropped": stats_one["frames_dropped"],
            "processed": stats_one["frames_processed"],
            "stage_ms": stats_one["stage_ms"],
            "fps_many": fps_many,
            "latency_many_p95": float(np.percentile(lat_many, 95)),
            "lag_max": float(lag.max()),
            "lag_over_1": float((lag > 1).mean() * 100),
            "messages_many": len(many),
            "server_sent": after["sent"] - before["sent"],
            "server_behind_pct": (after["sent_behind"] - before["sent_behind"])
            / max(1, after["sent"] - before["sent"])
            * 100,
            "load": os.getloadavg()[0],
        }
        if detections == "simulated" and args.memory_seconds > 0:
            result["memory"] = memory_run(url, args, background)
        return result
    finally:
        background.stop()
        out.unlink(missing_ok=True)


def memory_run(url: str, args: argparse.Namespace, background: Any) -> dict[str, Any]:
    """RSS of the server process while clients join and leave (churn per second)."""
    import threading

    samples: list[tuple[float, float]] = []
    stop = threading.Event()

    def sample() -> None:
        while not stop.is_set():
            samples.append((time.time(), rss_mb()))
            stop.wait(2.0)

    out = Path(tempfile.mkstemp(suffix=".json")[1])
    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    try:
        run_clients(url, args.clients, args.memory_seconds, args.churn, out, args.client_procs)
    finally:
        stop.set()
        sampler.join()
        out.unlink(missing_ok=True)
    rss = np.array([r for _, r in samples])
    warm = rss[len(rss) // 5 :] if len(rss) >= 5 else rss
    return {
        "seconds": args.memory_seconds,
        "churn": args.churn,
        "start_mb": float(warm[0]),
        "end_mb": float(warm[-1]),
        "max_mb": float(warm.max()),
        "drift_pct": float((warm[-1] - warm[0]) / warm[0] * 100),
        "clients_after": background.daemon.hub.subscriber_count,
    }


def report(results: list[dict[str, Any]], args: argparse.Namespace) -> str:
    stamp = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    lines = [
        "# Service latency and load",
        "",
        f"Machine: {platform.machine()}, {os.cpu_count()} CPU cores (shared with other jobs), "
        f"Python {platform.python_version()}; {stamp}.",
        f"Two 640x480 cameras replayed at 30 fps; {args.seconds:.0f} s per measurement; "
        "`python -m bench.serving.latency`.",
        "",
        "| detections | capture->WS p50 | p95 | pipeline fps | dropped/processed | "
        "detect / associate / track ms | fps with "
        f"{args.clients} clients | p95 with {args.clients} | client-side max lag | "
        "client msgs >1 behind | server sends >1 behind | load avg |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        st = {k: r["stage_ms"].get(k, 0.0) for k in ("detect", "associate", "track")}
        lines.append(
            f"| {r['detections']} | {r['latency_p50']:.1f} ms | {r['latency_p95']:.1f} ms | "
            f"{r['fps']:.1f} | {r['dropped']}/{r['processed']} | "
            f"{st['detect']:.1f} / {st['associate']:.1f} / {st['track']:.1f} | "
            f"{r['fps_many']:.1f} ({(r['fps_many'] / r['fps'] - 1) * 100:+.0f} %) | "
            f"{r['latency_many_p95']:.1f} ms | {r['lag_max']:.0f} | {r['lag_over_1']:.2f} % | "
            f"{r['server_behind_pct']:.2f} % of {r['server_sent']} | {r['load']:.1f} |"
        )
    for r in results:
        if "memory" in r:
            m = r["memory"]
            lines += [
                "",
                f"Memory ({r['detections']} detections, {args.clients} clients, {m['churn']} "
                f"leave and {m['churn']} join every second, {m['seconds']:.0f} s): server RSS "
                f"{m['start_mb']:.1f} MB after warm-up -> {m['end_mb']:.1f} MB at the end "
                f"(max {m['max_mb']:.1f} MB, drift {m['drift_pct']:+.1f} %); "
                f"{m['clients_after']} subscriptions left after all clients closed.",
            ]
    lines += [
        "",
        "Client-side lag counts snapshots published before a message arrived minus that "
        "message's seq (0 = newest); it includes the client processes' own backlog (200 Python "
        "clients parsing JSON on the same 2 cores as the server). Server sends >1 behind counts "
        "messages the server sent while 2+ newer snapshots existed: the server's own lag. "
        "Load avg: 1-minute load of the machine (other jobs included) at the end of the run. "
        "Stage times are the last frame set's. Latency includes detection "
        "(one batched SSDLite call for both cameras) when detections are `rendered`; "
        "`simulated` feeds the simulator's boxes at the same pipeline entry.",
    ]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "--worker":
        url, clients, seconds, churn, out = argv[1:6]
        worker_main(url, int(clients), float(seconds), float(churn), Path(out))
        return 0
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=15.0, help="per measurement")
    parser.add_argument("--clients", type=int, default=200, help="concurrent WebSocket clients")
    parser.add_argument(
        "--memory-seconds", type=float, default=60.0, help="churn run length (600 = issue target)"
    )
    parser.add_argument("--churn", type=int, default=20, help="clients replaced per second")
    parser.add_argument("--client-procs", type=int, default=2, help="client processes")
    parser.add_argument("--clip", type=int, default=90, help="pre-drawn frames replayed")
    parser.add_argument(
        "--detections", nargs="+", default=["rendered", "simulated"], help="scenarios"
    )
    parser.add_argument("--model", type=Path, default=None, help="model dir (default: demo)")
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    results = [scenario(d, args) for d in args.detections]
    text = report(results, args)
    return write_report(args.out, text)


if __name__ == "__main__":
    sys.exit(main())
