"""ONNX encoder speed: batch-1 latency and batch-1024 throughput on CPU.

Run ``python -m bench.model.encoder_speed [MODEL_DIR]``; without a model directory it trains a small
model on the indoor-2cam simulator preset first (a minute). Writes
``bench/results/encoder_speed.md``.

A "sample" is one person localized. The runtime averages the encoder over D fixed draws of mean
estimators, so one sample costs D encoder rows: the table reports the shipped D and D = 1 (one
draw, the paper's setting), both through the real :class:`models.mom.runtime.MomRuntime` (numpy
estimator construction included) and for the bare ONNX call.
"""

from __future__ import annotations

import datetime as dt
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.report import write_report
from models.mom.runtime import MomRuntime
from models.mom.sampling import InferenceSampler, SamplerConfig

RESULTS = Path(__file__).resolve().parents[1] / "results" / "encoder_speed.md"


def _timeit(fn, min_seconds: float = 1.0, min_calls: int = 20) -> float:
    """Median seconds per call over repeated timing rounds."""
    fn()
    times = []
    started = time.perf_counter()
    while time.perf_counter() - started < min_seconds or len(times) < min_calls:
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def _model_dir(argv: list[str]) -> Path:
    if argv:
        return Path(argv[0])
    from models.mom.training.train import train_model
    from models.simulate import simulate

    out = Path(tempfile.mkdtemp(prefix="mom-speed-")) / "model"
    data = simulate("indoor-2cam", frames=1500, seed=0).dataset
    train_model(data, out, epochs=30, progress=False)
    return out


def _boxes(runtime: MomRuntime, n: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    w, h = runtime.image_sizes[:, 0], runtime.image_sizes[:, 1]
    x0 = rng.uniform(0, w * 0.8, (n, runtime.num_cameras))
    y0 = rng.uniform(0, h * 0.5, (n, runtime.num_cameras))
    return np.stack([x0, y0, x0 + 0.1 * w, y0 + 0.4 * h], axis=-1).astype(np.float32)


def measure(model_dir: Path, threads: int) -> list[tuple[str, float, float]]:
    runtime = MomRuntime.load(model_dir, threads=threads)
    rows = []
    draws = runtime.sampler_config.draws
    for d in sorted({draws, 1}, reverse=True):
        if d != draws:  # the same model evaluated with one draw only
            runtime._sampler = InferenceSampler(
                SamplerConfig(**{**runtime.meta["sampler"], "draws": d})
            )
        one, batch = _boxes(runtime, 1), _boxes(runtime, 1024)
        latency = _timeit(lambda b=one: runtime.localize(b))
        throughput = 1024 / _timeit(lambda b=batch: runtime.localize(b))
        rows.append((f"MomRuntime.localize, D = {d}", latency * 1e3, throughput))
        run = runtime._session.run
        feeds = [
            dict(zip(("estimators", "mask"), runtime.encoder_inputs(b), strict=True))
            for b in (one, batch)
        ]
        latency = _timeit(lambda f=feeds[0], r=run: r(None, f))
        seconds = _timeit(lambda f=feeds[1], r=run: r(None, f))
        rows.append((f"ONNX encoder only, D = {d}", latency * 1e3, 1024 / seconds))
    return rows


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    model_dir = _model_dir(argv)
    meta = MomRuntime.load(model_dir).meta
    widths = meta.get("settings", {})
    described = (
        f"{meta['num_cameras']} cameras, {meta['observation']}, camera width "
        f"{widths.get('camera_width')}, global width {widths.get('global_width')}, "
        f"D = {meta['sampler']['draws']} draws"
    )
    lines = [
        "# MoM encoder speed (ONNX Runtime, CPU)",
        "",
        f"Machine: {platform.machine()} {platform.processor() or ''}, "
        f"{os.cpu_count()} cores, Python {platform.python_version()}, "
        f"date {dt.datetime.now(dt.UTC):%Y-%m-%d %H:%M} UTC. Model: {described}.",
        "One sample = one person localized (all cameras). D = draws averaged per sample.",
        "",
        "| path | threads | batch-1 latency (ms) | batch-1024 throughput (samples/s) |",
        "|---|---|---|---|",
    ]
    for threads in (1, 2):
        for name, latency, throughput in measure(model_dir, threads):
            lines.append(f"| {name} | {threads} | {latency:.3f} | {throughput:,.0f} |")
    return write_report(RESULTS, "\n".join(lines) + "\n")


if __name__ == "__main__":
    sys.exit(main())
