"""The demo's ``simulated`` detections: the simulator's noisy boxes as the detection stage.

Why here and not in ``capture``: capture gives frames; which boxes a detector would report is
the simulator's knowledge (``models.simulate``), and feeding them in place of the detector is a
choice of the service's demo wiring (``synthetic.detections: simulated``, see
:mod:`service.demo`). The stage reads each frame's ``seq`` (the scene frame index the synthetic
rig stamps) and ``camera`` (its position in the rig), so it works on any rig built from the same
scene, live or replayed.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from capture.rig import FrameSet
from models.detector.base import Detections
from models.simulate import Scene, make_scene
from service.settings import SyntheticSettings


def scene_for(synthetic: SyntheticSettings) -> Scene:
    """The scene ``synthetic`` settings describe (same settings, same scene: seeded).

    ``follow_setup``: one person who walks to wherever ``/setup`` tells them to stand.
    """
    scene = make_scene(
        synthetic.preset,
        seed=synthetic.seed,
        people=1 if synthetic.follow_setup else synthetic.people,
        fps=synthetic.fps,
        detector_profile=synthetic.detector_profile,
    )
    if synthetic.follow_setup:
        from models.simulate.following import install_follower

        install_follower(scene)
    return scene


class SimulatedDetections:
    """Detection stage: the simulator's noisy boxes and keypoints for each frame's scene index,
    followed by the profile's false positives for that camera (a real detector reports them
    too; they carry NaN keypoints, as a pose estimator finding no body in a box).

    ``cameras[k]`` is the scene camera behind rig camera ``k``.
    """

    keypoints = True  # the simulator gives every box its COCO-17 keypoints

    def __init__(self, scene: Scene, cameras: Sequence[int] | None = None) -> None:
        self.scene = scene
        self.cameras = list(range(scene.num_cameras)) if cameras is None else list(cameras)

    def __call__(self, frame_set: FrameSet) -> list[Detections]:
        out = []
        for frame in frame_set.frames:
            if frame is None:
                out.append(Detections.empty())
                continue
            observation = self.scene.observe(frame.seq)
            camera = self.cameras[frame.camera]
            boxes = np.asarray(observation.boxes, np.float32).reshape(-1, self.scene.num_cameras, 4)
            points = np.asarray(observation.keypoints, np.float32)
            joints = points.shape[2] if points.ndim == 4 else 17
            per_camera = boxes[:, camera, :]
            keypoints = points[:, camera] if points.ndim == 4 else np.zeros((0, joints, 3))
            false = np.asarray(observation.false_boxes, np.float32)
            if false.size:
                extra = false[camera].reshape(-1, 4)
                per_camera = np.concatenate([per_camera, extra])
                keypoints = np.concatenate([keypoints, np.full((len(extra), joints, 3), np.nan)])
            seen = np.all(np.isfinite(per_camera), axis=1)
            out.append(
                Detections(
                    per_camera[seen],
                    np.ones(int(seen.sum()), np.float32),
                    keypoints[seen].astype(np.float32),
                )
            )
        return out
