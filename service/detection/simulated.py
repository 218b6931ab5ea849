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
from service.stages import Unscheduled


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


class SimulatedDetections(Unscheduled):
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
            boxes, keypoints = observation.reported(self.cameras[frame.camera])
            out.append(
                Detections(
                    boxes.astype(np.float32),
                    np.ones(len(boxes), np.float32),
                    keypoints.astype(np.float32),
                )
            )
        return out
