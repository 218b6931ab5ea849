"""Regression gate on the streamed accuracy: association + tracking over a fixed simulated scene.

The shipped demo model (indoor-2cam), with a floor prior fitted and weighed as ``momloc train``
does it, serves 3 people walking in the ``indoor-2cam`` preset (seed 3, 450 frames = 30 s at
15 fps, detections shuffled per camera, frame timestamps), scored by
:func:`service.stream_eval.run_stream` with ``service.tracking.RECOMMENDED`` fed the
localizer's covariances (``service.measurements``), as the daemon runs it. Deterministic (seeded
scene, fixed model, numpy fits), so the bounds sit at the recorded figures with a small margin
for onnxruntime / BLAS rounding across machines. Recorded figures are in ``RECORDED``;
bench/stream_accuracy.py has the full table.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from models.mom_runtime import MomRuntime
from models.prior_policy import choose_policy
from models.simulate import simulate
from service.stream_eval import run_stream, scene_config

DEMO_MODEL = Path(__file__).resolve().parents[2] / "models" / "demo_model"
PROFILE = "nanodet"  # the measured default detector profile (models/simulate/profiles)
RECORDED = {  # gate 0.5 m, nanodet profile, service.tracking.RECOMMENDED fed the covariances
    # Re-recorded 2026-12-01 when the demo model was retrained on NanoDet's boxes on drawn frames
    # (its box geometry differs from the simulator's boxes scored here), and again when
    # multi_view_s = 0.1 joined RECOMMENDED (recall 71.36 -> 71.29, precision 67.89 -> 67.92).
    # Before the retraining: MOTA 43.77, recall 78.19, precision 69.85, 9 switches, mean 0.1691,
    # Acc@0.3 85.77, single 0.185, jitter 0.0475, lag 0.024. Re-recorded 2026-12-02 for the
    # issue-14 MOTA work (RECOMMENDED: serve_coast_s 0.5, likelihood assignment with gate 1.5 m +
    # 0.5 m/s, robust_chi2 16, doubt_outside; service/tracking.py). In brackets: before it.
    # Worse here: id switches 11 -> 14, Acc@0.3 85.22 -> 84.29, mean 0.1694 -> 0.1704, single
    # 0.185 -> 0.188 (on the bench's 4 seeds id switches fell 34 -> 25).
    "mota": 46.37,  # 36.80
    "recall": 72.70,  # 71.29
    "precision": 74.19,  # 67.92
    "id_switches": 14,  # 11
    "mean": 0.1704,  # 0.1694
    "acc@0.3": 84.29,  # 85.22
    "single_mean": 0.188,  # 0.185
    "jitter_m": 0.0554,  # 0.0560
    "lag_s": 0.029,  # 0.036
}


def demo_with_prior(out: Path) -> Path:
    """The demo encoder with a floor prior fitted and weighed as ``momloc train`` does it
    (``models.prior_policy.choose_policy``: prior fitted on a separate simulated recording,
    weights per view class and the encoder/prior error ratio from its validation rows), so the
    served positions and their covariances are those of a freshly trained model; numpy only, so
    the gate is deterministic across machines."""
    demo = MomRuntime.load(DEMO_MODEL)
    data = simulate(scene_config("indoor-2cam", 3, PROFILE), frames=1500, seed=1000).dataset
    val = np.sort(np.random.default_rng(0).permutation(data.n)[: data.n * 15 // 100])
    entry, _ = choose_policy(data, "bbox", val, demo.localize(data.boxes[val]))
    out.mkdir(parents=True, exist_ok=True)
    shutil.copy(DEMO_MODEL / "encoder.onnx", out / "encoder.onnx")
    (out / "model.json").write_text(json.dumps({**demo.meta, "floor_prior": entry}))
    return out


@pytest.fixture(scope="module")
def scores(tmp_path_factory) -> dict:
    runtime = MomRuntime.load(demo_with_prior(tmp_path_factory.mktemp("model")))
    return run_stream(runtime, scene_config("indoor-2cam", 3, PROFILE), seed=3, frames=450)


def test_counts_and_mota(scores):
    m = scores[0.5]
    assert m["gt"] > 1200 and m["frames"] == 450
    assert m["mota"] >= RECORDED["mota"] - 1.0, m["mota"]
    assert m["recall"] >= RECORDED["recall"] - 1.0, m["recall"]
    assert m["precision"] >= RECORDED["precision"] - 1.0, m["precision"]
    assert m["id_switches"] <= RECORDED["id_switches"] + 1, m["id_switches"]
    assert scores[1.0]["mota"] >= m["mota"]  # a looser gate never scores worse


def test_matched_errors(scores):
    m = scores[0.5]
    assert m["mean"] <= RECORDED["mean"] + 0.005, m["mean"]
    assert m["acc@0.3"] >= RECORDED["acc@0.3"] - 1.0, m["acc@0.3"]
    single = m["by_views"]["1"]
    assert single["n"] > 300
    assert single["mean"] <= RECORDED["single_mean"] + 0.01, single["mean"]
    assert m["by_views"]["2"]["mean"] < single["mean"]  # a second view corrects the depth


def test_jitter_and_lag(scores):
    m = scores[0.5]
    # 74 standing pairs since coasting tracks are served for 0.5 s only (was > 80 at 1.5 s)
    assert m["jitter_n"] > 60 and m["lag_n"] > 500
    assert m["jitter_m"] <= RECORDED["jitter_m"] + 0.002, m["jitter_m"]
    assert abs(m["lag_s"] - RECORDED["lag_s"]) <= 0.02, m["lag_s"]
