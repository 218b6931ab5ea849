"""Offline served-accuracy run: simulated detections → the daemon's chain → stream metrics.

The chain the daemon runs per frame set (:class:`service.pipeline.chain.Chain`: association, the
set-up area, lone-view correction, :class:`service.tracking.tracker.Tracker`) driven by frame
timestamps (``frame / fps``, no real-time pacing) over a simulated scene, and what it serves scored
by :mod:`models.data.stream_metrics`.

What counts as truth: every person *in view*, i.e. whose true body box keeps at least
``MIN_VISIBLE_FRACTION`` of its area inside at least one camera's image, whether or not the
simulated detector reports them. A person the detector misses in every camera is a miss of the
served stream (the tracker may still coast on them, and is credited when it does); a sliver at
an image border is not expected. The camera count of the split is the number of cameras whose
*detector* reports the person that frame (0: coasting).

Detections are shuffled per camera (nothing of the true association leaks) and include the
detector's false positives when the scene's profile makes them (``FrameObservation.false_boxes``).
Everything is seeded, so a run is deterministic.

Example::

    runtime = MomRuntime.load("model/")
    scores = run_stream(runtime, scene_config("indoor-2cam", people=3), seed=7, frames=600)
    print(scores[0.5]["mota"], scores[0.5]["by_views"]["1"]["mean"])
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence

import numpy as np

from models.data.stream_metrics import StreamScorer
from models.detector.base import Detections
from models.simulate import FrameObservation, Scene, SceneConfig, get_config
from service.detection.box_carrier import BoxCarrier
from service.pipeline.chain import Chain, OutsideArea
from service.stages import Association, Track
from service.tracking.association import (
    DEFAULT_MAX_ERROR_PX,
    DEFAULT_MAX_VIEW_GAP_M,
    LocalizationModel,
    associate,
)
from service.tracking.tracker import RECOMMENDED, Tracker
from service.tracking.view_bias import ViewBias

MIN_VISIBLE_FRACTION = 0.5
GATES = (0.5, 1.0)


def scene_config(preset: str, people: int | None = None, profile: str | None = None) -> SceneConfig:
    """A preset with ``people`` and, when given, a detector ``profile`` (name or JSON path)."""
    return get_config(preset, people=people, detector_profile=profile)


def in_view(true_boxes: np.ndarray, image_sizes: np.ndarray, min_fraction: float) -> np.ndarray:
    """[P] bool: the true box [P, K, 4] keeps ``min_fraction`` of its area inside some image."""
    size = np.asarray(image_sizes, dtype=np.float64)[None]  # [1, K, 2]
    lo = np.clip(true_boxes[..., :2], 0.0, size)
    hi = np.clip(true_boxes[..., 2:], 0.0, size)
    inside = np.prod(np.clip(hi - lo, 0.0, None), axis=-1)
    area = np.prod(true_boxes[..., 2:] - true_boxes[..., :2], axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(area > 0, inside / area, 0.0)
    return np.any(np.nan_to_num(fraction) >= min_fraction, axis=1)


def frame_detections(obs: FrameObservation, rng: np.random.Generator) -> list[Detections]:
    """Per camera the detector's report (people and false positives,
    :meth:`FrameObservation.reported`), shuffled, every box with its COCO-17 keypoints (NaN for
    a false box), as :class:`service.detection.simulated.SimulatedDetections` hands them to the
    daemon: the association reads them for a keypoint model only."""
    out = []
    for k in range(obs.boxes.shape[1]):
        boxes, points = obs.reported(k)
        order = rng.permutation(len(boxes))
        out.append(
            Detections(
                boxes[order].astype(np.float32).reshape(-1, 4),
                np.ones(len(order), np.float32),
                points[order].astype(np.float32),
            )
        )
    return out


class ScheduledBoxes:
    """The scheduled detector of the daemon, replayed: the detector's report of every
    ``every``-th frame set arrives ``delay`` frame sets later and corrects a per-camera
    :class:`~service.detection.box_carrier.BoxCarrier` (Kalman filter only: the simulator draws
    no images for optical flow), whose carried boxes are served on every frame set. So the
    stream's accuracy with detected-every-frame and scheduled boxes compares in one bench."""

    def __init__(self, every: int, delay: int) -> None:
        self.every, self.delay = int(every), int(delay)
        self.carriers: list[BoxCarrier] = []
        self.pending: dict[int, list[Detections]] = {}

    def __call__(self, i: int, t: float, found: list[Detections], fps: float) -> list[Detections]:
        if not self.carriers:
            self.carriers = [BoxCarrier(flow=False) for _ in found]
        if i % self.every == 0:
            self.pending[i] = found
        ready = self.pending.pop(i - self.delay, None)
        out = []
        for k, carrier in enumerate(self.carriers):
            if ready is not None:
                det = ready[k]
                carrier.correct((i - self.delay) / fps, det.boxes, det.scores, det.keypoints)
            carried = carrier.advance(t)
            out.append(Detections(carried.boxes, carried.scores, carried.keypoints))
        return out


def run_stream(
    runtime: LocalizationModel,
    config: SceneConfig,
    seed: int,
    frames: int,
    *,
    tracker: Tracker | None = None,
    gates: Sequence[float] = GATES,
    max_error_px: float = DEFAULT_MAX_ERROR_PX,
    max_view_gap_m: float = DEFAULT_MAX_VIEW_GAP_M,
    min_visible_fraction: float = MIN_VISIBLE_FRACTION,
    use_covariance: bool = True,
    view_bias: ViewBias | bool = True,
    outside_area: OutsideArea = "drop",
    on_frame: Callable[[int, list[Association], list[Track]], None] | None = None,
    postures: bool = True,
    detect_every: int = 1,
    detect_delay: int = 0,
) -> dict[float, dict]:
    """Stream metrics per gate (metres → :meth:`StreamScorer.result`) of one scene run.

    ``tracker`` defaults to ``Tracker(fps_hint=scene fps, **RECOMMENDED)``; ``use_covariance``
    hands the associations' covariances to the tracker as its measurement noise, the same way
    the live pipeline does (:func:`service.tracking.measurements.measurement_covariances`);
    ``view_bias`` corrects single-view positions by their track's lone-view offset as the
    pipeline does (:class:`service.tracking.view_bias.ViewBias`; ``True``: the default one,
    ``False``: none);
    ``outside_area``: what the chain does with people outside the model's set-up area
    (:mod:`service.pipeline.chain`);
    ``on_frame(i, associations, tracks)`` taps every frame (diagnostics, other scorers);
    ``postures``: seated and lying boxes read as standing ones (:mod:`service.tracking.posture`);
    ``detect_every`` > 1 models the daemon's scheduled detector (:class:`ScheduledBoxes`).
    """
    scene = Scene(config, seed=seed)
    tracker = tracker if tracker is not None else Tracker(fps_hint=scene.fps, **RECOMMENDED)
    rng = np.random.default_rng([seed, 77])
    scorers = {float(g): StreamScorer(g) for g in gates}
    chain = Chain(
        tracker,
        associate=functools.partial(associate, max_view_gap_m=max_view_gap_m),
        max_error_px=max_error_px,
        outside_area=outside_area,
        use_covariance=use_covariance,
        view_bias=None if view_bias is False else view_bias,
        postures=postures,
    )
    delivered = [True] * int(runtime.num_cameras)
    schedule = ScheduledBoxes(detect_every, detect_delay) if detect_every > 1 else None
    for i in range(frames):
        obs = scene.observe(i)
        t = i / scene.fps
        detections = frame_detections(obs, rng)
        if schedule is not None:
            detections = schedule(i, t, detections, scene.fps)
        result, tracks = chain(t, detections, runtime, delivered, i)
        if on_frame is not None:
            on_frame(i, result, tracks)
        want = in_view(obs.true_boxes, scene.image_sizes, min_visible_fraction)
        views = np.isfinite(obs.boxes).all(axis=2).sum(axis=1)
        served_ids = [tr.id for tr in tracks]
        served_xy = np.array([[tr.x, tr.y] for tr in tracks]).reshape(-1, 2)
        for scorer in scorers.values():
            scorer.add(t, obs.track[want], obs.world[want, :2], served_ids, served_xy, views[want])
    return {g: s.result() for g, s in scorers.items()}
