"""Machine time of the web set-up flow, Start to live positions, on the synthetic scene.

The daemon runs as ``momloc serve`` would on a first run (no model: set-up mode), on the
``indoor-2cam`` scene with one simulated person who follows the set-up instructions
(``synthetic.follow_setup``), and is driven through the same HTTP calls the /setup page makes:
Start (a R x C grid, S seconds per mark, the page's default move and countdown times), Train
(the adaptive schedule unless ``--epochs``), then the check step on four of the marks. Reported:
recording, training and Start-to-positions times (positions appear with the quick first model;
``start_to_final_model_s`` is when the final one is loaded), training epochs and validation
error, the check's median error (the check runs on the final model), and for comparison
``momloc eval`` of the final and the first model (``model.first``) on a recording of the same
person standing on the same marks (``momloc collect --source synthetic``, same scene): per row,
and ``--served`` (scored as the check scores the live stream: the figure the check must match).

    .venv/bin/python -m bench.setup.setup_flow [--grid 3x3] [--seconds 20] [--epochs N]

Prints one JSON object; ``bench/results/setup_flow.md`` keeps the runs' figures.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from service.api.server import serve_in_thread
from service.daemon import build_daemon
from service.settings import load_settings


def wait(read: Any, done: Any, timeout: float) -> Any:
    deadline = time.time() + timeout
    while not done(value := read()):
        if time.time() > deadline:
            raise TimeoutError(str(value))
        time.sleep(0.5)
    return value


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", default="3x3")
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--epochs", type=int, default=None)
    parser.add_argument("--profile", default="nanodet", help="simulated detector profile")
    args = parser.parse_args()
    data_dir = Path(tempfile.mkdtemp(prefix="momloc-setup-bench-"))
    settings = load_settings(
        None,
        cameras=[{"type": "synthetic", "index": k} for k in range(2)],
        synthetic={"people": 1, "follow_setup": True, "detector_profile": args.profile},
        data_dir=data_dir,
    )
    daemon = build_daemon(settings)
    server = serve_in_thread(daemon)
    base = f"http://127.0.0.1:{server.port}"

    def status() -> dict[str, Any]:
        return httpx.get(base + "/v1/setup/status", timeout=30).json()

    try:
        wait(lambda: daemon.pipeline.image_sizes, lambda s: None not in s, 60)
        start = {"grid": args.grid, "room": "10x10", "seconds": args.seconds, "out": "room.npz"}
        t0 = time.time()
        httpx.post(base + "/v1/setup/start", json=start, timeout=30).raise_for_status()
        recorded = wait(status, lambda s: s["state"] != "running", 3600)
        t_recorded = time.time()
        body = {} if args.epochs is None else {"epochs": args.epochs}
        httpx.post(base + "/v1/setup/train", json=body, timeout=30).raise_for_status()
        seen: dict[str, float] = {}

        def training() -> dict[str, Any]:
            """The training state; notes when positions first appear and the first model."""
            state = status()["training"]
            if state.get("first_model") and "first" not in seen:
                seen["first"] = time.time()
            if "positions" not in seen and httpx.get(base + "/v1/positions").json()["people"]:
                seen["positions"] = time.time()
            return state

        trained = wait(training, lambda t: t["state"] != "running", 3600)
        t_trained = time.time()
        wait(lambda: httpx.get(base + "/v1/positions").json()["people"], bool, 60)
        t_positions = seen.get("positions", time.time())
        httpx.post(base + "/v1/setup/verify", json={}, timeout=30).raise_for_status()
        check = wait(lambda: status()["verify"], lambda v: v["state"] != "running", 600)
        marks = check.get("marks") or []
        evaluated = eval_at(marks, data_dir, settings.synthetic, args.profile, "model")
        first_eval = None
        if (data_dir / "model.first").is_dir():
            first_eval = eval_at(marks, data_dir, settings.synthetic, args.profile, "model.first")
        print(
            json.dumps(
                {
                    "grid": args.grid,
                    "seconds_per_mark": args.seconds,
                    "profile": args.profile,
                    "recording_state": recorded["state"],
                    "rows": recorded.get("new_rows"),
                    "recording_s": round(t_recorded - t0, 1),
                    "training_state": trained["state"],
                    "training_s": round(t_trained - t_recorded, 1),
                    "epochs": trained["epoch"],
                    "val_error_m": trained["val_error_m"],
                    "first_model": trained.get("first_model"),
                    "first_model_s": round(seen["first"] - t_recorded, 1) if seen else None,
                    "start_to_positions_s": round(t_positions - t0, 1),
                    "start_to_final_model_s": round(t_trained - t0, 1),
                    "check": (check.get("summary") or {}).get("text"),
                    "check_marks": check.get("marks"),
                    "eval_same_marks": evaluated,
                    "first_model_eval_same_marks": first_eval,
                }
            )
        )
    finally:
        server.stop()
        if daemon.training is not None:
            daemon.training.cancel()


def eval_at(
    marks: list[dict], data_dir: Path, synthetic: Any, profile: str, model: str
) -> dict | None:
    """``momloc eval`` of ``data_dir/model`` on a synthetic recording at the checked marks."""
    if not marks:
        return None
    listed = "\n".join(f"  - {{name: {m['name']}, x: {m['x']}, y: {m['y']}}}" for m in marks)
    (data_dir / "check-marks.yaml").write_text("marks:\n" + listed + "\n")
    cli = [sys.executable, "-m", "service.cli"]
    out = data_dir / "check.npz"
    if not out.exists():
        subprocess.run(
            [*cli, "collect", "--source", "synthetic", "--preset", synthetic.preset,
             "--seed", str(synthetic.seed), "--profile", profile,
             "--marks", str(data_dir / "check-marks.yaml"), "--seconds", "5", "--out", str(out)],
            check=True, capture_output=True,
        )  # fmt: skip
    result = subprocess.run(
        [*cli, "eval", str(data_dir / model), str(out), "--json"],
        check=True, capture_output=True, text=True,
    )  # fmt: skip
    metrics = json.loads(result.stdout)
    served = subprocess.run(
        [*cli, "eval", str(data_dir / model), str(out), "--served", "--json"],
        check=True, capture_output=True, text=True,
    )  # fmt: skip
    return {
        **{k: metrics[k] for k in ("n", "mean", "median")},
        **per_mark(data_dir / model, out),
        "served": json.loads(served.stdout),
    }


def per_mark(model_dir: Path, recording: Path) -> dict[str, Any]:
    """The check's statistic on the offline recording: median error per mark, then the median
    over marks (``momloc eval`` pools the rows, so marks with more kept rows weigh more)."""
    from models.data.dataset import MomDataset
    from models.mom.evaluate import predict
    from models.mom.runtime import MomRuntime

    data = MomDataset.load(recording)
    runtime = MomRuntime.load(model_dir)
    errors = np.linalg.norm(predict(runtime, data) - data.world[:, :2], axis=1)
    labels = np.round(data.world[:, :2], 3)
    medians = {
        f"{x:.2f},{y:.2f}": round(float(np.nanmedian(errors[(labels == (x, y)).all(axis=1)])), 3)
        for x, y in np.unique(labels, axis=0)
    }
    return {
        "per_mark_median": medians,
        "median_over_marks": float(np.median(list(medians.values()))),
    }


if __name__ == "__main__":
    main()
