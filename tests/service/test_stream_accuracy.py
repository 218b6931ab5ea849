"""Regression gate on the streamed accuracy: association + tracking over a fixed simulated scene.

The shipped demo model (indoor-2cam), with a floor prior fitted and weighed as ``momloc train``
does it, serves 3 people walking in the ``indoor-2cam`` preset (seed 3, 450 frames = 30 s at
15 fps, detections shuffled per camera, frame timestamps), scored by
:func:`service.offline.stream_eval.run_stream` with ``service.tracking.tracker.RECOMMENDED`` fed the
localizer's covariances (``service.tracking.measurements``) and single-view positions corrected by
their track's lone-view offset (``service.tracking.view_bias``), as the daemon runs it.
Deterministic (seeded scene, fixed model, numpy fits), so the bounds sit at the recorded figures
with a small margin for onnxruntime / BLAS rounding across machines. Recorded figures are in
``RECORDED``; bench/serving/stream_accuracy.py has the full table.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from models.mom.prior_policy import choose_policy
from models.mom.runtime import MomRuntime
from models.simulate import simulate
from service.offline.stream_eval import run_stream, scene_config

DEMO_MODEL = Path(__file__).resolve().parents[2] / "models" / "demo_model"
PROFILE = "nanodet"  # the measured default detector profile (models/simulate/profiles)
RECORDED = {  # gate 0.5 m, nanodet profile, service.tracking.tracker.RECOMMENDED fed the
    # covariances
    # Re-recorded 2026-12-01 when the demo model was retrained on NanoDet's boxes on drawn frames
    # (its box geometry differs from the simulator's boxes scored here), and again when
    # multi_view_s = 0.1 joined RECOMMENDED (recall 71.36 -> 71.29, precision 67.89 -> 67.92).
    # Before the retraining: MOTA 43.77, recall 78.19, precision 69.85, 9 switches, mean 0.1691,
    # Acc@0.3 85.77, single 0.185, jitter 0.0475, lag 0.024. In brackets: the tracker before
    # issue 14 on the former model. Re-recorded 2026-12-02 when run_stream (and the pipeline)
    # began correcting single-view positions by their track's lone-view offset
    # (service.tracking.view_bias); without it: MOTA 36.80, recall 71.29, precision 67.92, 11
    # switches, mean 0.1694, Acc@0.3 85.22, single 0.185, jitter 0.0560, lag 0.036. Re-recorded the
    # same day for the MOTA work (RECOMMENDED: coasting served 0.5 s, likelihood assignment, gate
    # 1.5 m + 0.5 m/s, robust_chi2 16, doubt_outside; service/tracking/tracker.py); with the
    # settings before it (bench variant 12-01) this code gives MOTA 41.17, recall 72.18, precision
    # 70.35, 8 switches, mean 0.1619, Acc@0.3 88.69, single 0.182, jitter 0.0448, lag 0.045. Worse
    # now here: 11 switches (8), Acc@0.3 87.77 (88.69), jitter 0.0534 (0.0448); on the bench's 4
    # seeds MOTA 65.0 -> 71.0 %, id switches 18 -> 25, jitter 5.86 -> 4.26 cm.
    # Re-recorded 2026-12-03 (issue 23) with the nanodet profile rebuilt from tight-box evidence
    # and the real-room defaults (association floor gate, tracker measurement_scale 9, birth
    # clearance and merging: bench/results/real_cmc_chain_tuning.md). Before, in order: MOTA
    # 51.63, recall 72.18, precision 78.53, 11 switches, mean 0.1636, Acc@0.3 87.77, single
    # 0.182, jitter 0.0534, lag 0.024 (in brackets below: the tracker before issue 14).
    # Re-recorded 2026-12-03 when image continuity joined RECOMMENDED (tracker image_std_h;
    # bench/results/real_cmc_chain_tuning.md); before: MOTA 84.94, recall 93.03, precision
    # 92.27, 4 switches, mean 0.1534, Acc@0.3 91.87, single 0.179, jitter 0.0260, lag 0.040
    # (seeds 7 / 8 of the same scene: 91.56 / 87.62 before, 91.56 / 87.77 with it).
    # Re-recorded 2026-12-03 when the association began taking the tracker's served tracks as
    # anchors (service.pipeline.chain track_anchors; real room: MOTA +2.3 to +8.1 points,
    # bench/results/real_cmc_chain_tuning.md); before: MOTA 84.64, recall 92.88, precision
    # 92.13, 4 switches, mean 0.1546, Acc@0.3 91.61, jitter 0.0259, lag 0.041 (seed 7: 91.56
    # before and with it).
    # Re-recorded 2026-12-03 (issue 27) when the demo model was rebuilt with a set-up area and a
    # height model (tools/make_demo_model.py; its boxes now come from the OpenVINO INT8 engine).
    # Before: MOTA 82.94, recall 91.77, precision 91.63, 6 switches, mean 0.1501, Acc@0.3 92.00,
    # single 0.181, jitter 0.0263, lag 0.039. Seeds 7 / 8: MOTA 91.56 / 87.47 before, 88.67 /
    # 89.18 now. The rebuilt encoder is jitterier for standing people: 2.63 / 1.56 / 4.12 cm
    # before, 6.00 / 3.77 / 4.40 cm now (seeds 3 / 7 / 8, same standing pairs +-4). With it, a
    # seated replacement began to be judged by its floor position as detected alone (the height
    # check dropped every real sitter; service.pipeline.chain): 29 more false positives here
    # (MOTA 88.65, precision 96.51 before); seeds 7 / 8 unchanged.
    # Re-recorded 2026-12-06 (issue 23) when the nanodet profile's real-room edge rows were
    # measured against the simulated room's new geometry (reference heads at the annotation's
    # 0.9 of the stature, the walk stepped at >= 15 fps: bench/results/sim_vs_real_occlusion.md);
    # bottom-edge bias -0.009 -> -0.017 ... -0.041 h above 100 px, edge correlation 0.5 -> 0.81 s.
    # Before: MOTA 86.28, recall 92.28, precision 94.24, 5 switches, mean 0.1501, Acc@0.3 92.36,
    # single 0.164, jitter 0.0600, lag 0.042. Seeds 7 / 8: MOTA 88.96 / 89.18 before, 92.52 /
    # 87.62 now (the three seeds' mean 88.1 -> 88.4).
    # Re-recorded 2026-12-06 (issue 23) when the tracker began to learn its measurement scale
    # (service.tracking.noise_scale: it settles at its floor, 3, here; the fixed 9 before).
    # Before: MOTA 85.01, recall 91.69, precision 93.57, 5 switches, mean 0.1520, Acc@0.3 92.15,
    # single 0.172, jitter 0.0551, lag 0.037. Seeds 7 / 8: MOTA 92.52 / 87.62 before, 92.37 /
    # 89.10 now (the three seeds' mean 88.4 -> 88.7; matched mean 0.143 / 0.163 -> 0.125 /
    # 0.141 m).
    "mota": 84.50,  # 10.3
    "recall": 91.62,  # 71.2
    "precision": 93.14,  # 54.3
    "id_switches": 5,  # 13
    "mean": 0.1424,  # 0.205
    "acc@0.3": 93.04,  # 76.0
    "single_mean": 0.170,  # 0.240
    "jitter_m": 0.0286,  # 0.090
    "lag_s": 0.023,  # 0.018
}


def demo_with_prior(out: Path) -> Path:
    """The demo encoder with a floor prior fitted and weighed as ``momloc train`` does it
    (``models.mom.prior_policy.choose_policy``: prior fitted on a separate simulated recording,
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
    # 165 standing pairs (coasting tracks are served for 0.5 s only)
    assert m["jitter_n"] > 60 and m["lag_n"] > 500
    assert m["jitter_m"] <= RECORDED["jitter_m"] + 0.002, m["jitter_m"]
    assert abs(m["lag_s"] - RECORDED["lag_s"]) <= 0.02, m["lag_s"]
