"""The embedded demo: the full daemon on the simulator's scene with the shipped demo model.

Nothing is special-cased: the demo builds ordinary :class:`~service.settings.Settings` with
``synthetic`` cameras and hands them to the same ``build_daemon`` as ``momloc serve``. The only
choice is where the boxes come from (``synthetic.detections``):

- ``rendered`` (default): the simulator draws both cameras' frames (``models.simulate.render``)
  and the shipped detector (NanoDet) finds the people in them, so the demo runs the whole chain
  a webcam rig runs. The shipped demo model was trained on that detector's boxes on drawn frames
  of the same room (``tools/make_demo_model.py``). Costs ~10 ms of drawing and ~30-40 ms of
  detection CPU per frame set on 2 cores.
- ``simulated``: the simulator's boxes enter the pipeline at the detection stage instead (no
  drawing, no detector): for machines too small to run the detector at the demo's rate. They are
  as blind as the shipped detector (``synthetic.detector_profile``, default ``nanodet``: misses
  by size, occlusion and truncation, edge errors, false positives, persisting over frames;
  ``--profile ideal`` for the former kind noise).

Why rendered is the default: measured with :func:`replay_demo` on frames 30..599
(``bench/results/demo_scene.md``), the drawn frames through NanoDet localise the three people at
least as well as the simulated boxes do; the price is a lower precision (tracks coasting on
after brief misses). SSDLite found too few of the drawn people
(``bench/results/render_recall*.md``), which is why ``simulated`` used to be the default.
``MOMLOC_SYNTHETIC__DETECTIONS`` still chooses either.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from typing import Literal

import numpy as np

from common.errors import MomlocError
from models.simulate import get_config
from service.settings import DEMO_MODEL_DIR, Settings, load_settings

DEMO_PRESET = "indoor-2cam"  # the demo model's cameras and training scene
# What the demo plays: the same room and cameras with a sofa and a coffee table in the lounge
# zone and one more person sitting on the sofa the whole time (models.simulate.presets, issue 27):
# the zone stays occupied while the others walk.
DEMO_SCENE = "demo-lounge"
DEMO_SEED = 7
DEMO_PEOPLE = 3
DEMO_FPS = 30.0
# Two zones in the 10 m x 10 m demo room, so the map, /v1/zones and MQTT have something to show:
# a rectangle and a concave L (MOMLOC_ZONES replaces them).
DEMO_ZONES = [
    {"name": "kitchen", "polygon": [[0.5, 0.5], [4.0, 0.5], [4.0, 4.0], [0.5, 4.0]]},
    {
        "name": "lounge",
        "polygon": [[5.0, 5.0], [9.5, 5.0], [9.5, 9.5], [8.5, 9.5], [8.5, 8.5], [5.0, 8.5]],
    },
]
DEMO_DETECTIONS: Literal["rendered", "simulated"] = "rendered"


def demo_settings(
    *,
    host: str | None = None,
    port: int | None = None,
    detections: Literal["rendered", "simulated"] | None = None,
    people: int | None = None,
    seed: int | None = None,
    profile: str | None = None,
    scene: str = DEMO_SCENE,
) -> Settings:
    """Settings for the demo scene (``scene``: another preset with the demo's cameras, e.g.
    ``DEMO_PRESET`` for the walkers alone); ``MOMLOC_*`` environment variables still apply."""
    config = get_config(scene)
    synthetic = {
        "preset": scene,
        "seed": DEMO_SEED if seed is None else seed,
        "people": DEMO_PEOPLE if people is None else people,
        "fps": DEMO_FPS,
    }
    env = {key.upper() for key in os.environ}
    if detections is None and "MOMLOC_SYNTHETIC__DETECTIONS" not in env:
        detections = DEMO_DETECTIONS
    if detections is not None:
        synthetic["detections"] = detections
    if profile is not None:
        synthetic["detector_profile"] = profile
    return load_settings(
        None,
        cameras=[{"type": "synthetic", "index": k} for k in range(len(config.cameras))],
        model_dir=DEMO_MODEL_DIR,
        synthetic=synthetic,
        host=host,
        port=port,
        zones=None if "MOMLOC_ZONES" in os.environ else DEMO_ZONES,
    )


@dataclass(frozen=True)
class DemoScore:
    """End-to-end accuracy of the demo scene, frame by frame against the simulator's truth.

    ``errors`` are the distances (m) of reported people matched one-to-one (Hungarian, at most
    ``MATCH_M``) to people in view; ``recall`` = matches / people in view, ``precision`` = matches
    / reported people; ``ids`` = distinct track ids reported.
    """

    frames: int
    errors: np.ndarray
    in_view: int
    reported: int
    ids: int

    @property
    def recall(self) -> float:
        return len(self.errors) / max(self.in_view, 1)

    @property
    def precision(self) -> float:
        return len(self.errors) / max(self.reported, 1)

    def summary(self) -> dict[str, float]:
        e = self.errors
        return {
            "frames": self.frames,
            "mean_m": round(float(e.mean()), 3) if e.size else float("nan"),
            "median_m": round(float(np.median(e)), 3) if e.size else float("nan"),
            "within_0.5m": round(float(np.mean(e < 0.5)), 3) if e.size else 0.0,
            "recall": round(self.recall, 3),
            "precision": round(self.precision, 3),
            "ids": self.ids,
        }


MATCH_M = 1.0


def replay_demo(settings: Settings, frames: int = 600, warmup: int = 30) -> DemoScore:
    """Run the demo's daemon offline on scene frames 0..frames-1 (scene timestamps, no clock).

    People "in view" are those whose true box lies at least half inside some camera's image:
    the same truth for simulated and rendered detections, so the two modes compare directly.
    """
    from scipy.optimize import linear_sum_assignment

    from capture.rig import FrameSet
    from capture.synthetic import SyntheticRig
    from capture.worker import Frame
    from service.daemon import build_daemon
    from service.detection.simulated import scene_for

    # Offline means every frame set gets its own detection: the live scheduler detects on wall
    # clock time beside the pipeline, so its rate (and the score) would follow the machine's load.
    inline = settings.detection.model_copy(update={"schedule": "every_frame"})
    # the score is of this model: the room must not learn (or write labels) while replaying
    fixed = settings.learning.model_copy(update={"enabled": False})
    daemon = build_daemon(settings.model_copy(update={"detection": inline, "learning": fixed}))
    pipeline, rig = daemon.pipeline, daemon.pipeline.rig
    if not isinstance(rig, SyntheticRig):
        raise MomlocError("replay_demo: the settings must describe synthetic cameras")
    if settings.synthetic.detections == "simulated":
        rig.render_every = 0  # boxes only: nothing needs drawing
    scene = scene_for(settings.synthetic)  # seeded: the very scene the rig shows
    sizes = np.array([scene.cameras[k].image_size for k in rig.cameras], np.float64)
    errors: list[float] = []
    in_view = reported = 0
    ids: set[int] = set()
    for i in range(frames):
        produced = rig.produce(i).frames
        stamped: list[Frame | None] = [
            None if f is None else dataclasses.replace(f, timestamp=1e6 + i / rig.fps)
            for f in produced
        ]
        snapshot = pipeline.process(FrameSet(stamped, 0.0))
        if i < warmup:  # tracks confirmed
            continue
        truth = scene.observe(i)
        boxes = truth.true_boxes[:, rig.cameras]  # [P, K, 4]
        lo = np.clip(boxes[..., :2], 0, sizes)
        hi = np.clip(boxes[..., 2:], 0, sizes)
        inside = np.prod(np.clip(hi - lo, 0, None), -1)
        area = np.prod(boxes[..., 2:] - boxes[..., :2], -1)
        seen = np.nan_to_num(inside / np.where(area > 0, area, np.nan)) >= 0.5
        gt = truth.world[seen.any(1), :2]
        got = np.array([[p["x"], p["y"]] for p in snapshot.people]).reshape(-1, 2)
        in_view, reported = in_view + len(gt), reported + len(got)
        ids |= {p["id"] for p in snapshot.people}
        if len(got) and len(gt):
            cost = np.linalg.norm(got[:, None] - gt[None], axis=2)
            r, c = linear_sum_assignment(cost)
            errors.extend(d for d in cost[r, c] if d <= MATCH_M)
    pipeline.stop()  # the camera-shift worker thread
    return DemoScore(frames - warmup, np.array(errors), in_view, reported, len(ids))
