"""Detection feeds for guided collection: the synthetic scene with a person who follows the plan.

The synthetic feed runs as fast as the simulator goes (simulated time, no sleeping), so an
unattended collection of 9 marks x 20 s takes seconds. It uses exactly the cameras of
``momloc simulate --preset NAME --seed S``, so a model trained on the collected marks can be
evaluated on a dense ``simulate`` file of the same scene.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from models.simulate import get_config
from models.simulate.scripted import Segment, scripted_scene
from service.setup.collector import FeedFrame, Step


class SyntheticFeed:
    """Simulated detections of one scripted person walking the collection plan."""

    def __init__(self, preset: str, seed: int) -> None:
        self.config = get_config(preset)
        self.seed = seed
        self.image_sizes = np.array([c.image_size for c in self.config.cameras], np.int32)
        self.room = self.config.room
        self._fps = self.config.fps
        self.scene = None

    def prepare(self, steps: list[Step]) -> None:
        """Script the simulated person to follow ``steps`` back to back."""
        segments = [Segment(s.start, s.end, s.seconds) for s in steps]
        self.scene = scripted_scene(self.config, self.seed, segments)
        self._begins = {id(step): sum(s.seconds for s in steps[:i]) for i, step in enumerate(steps)}

    def frames(self, step: Step) -> Iterator[FeedFrame]:
        begin = self._begins[id(step)]
        first = round(begin * self._fps)
        last = max(first + 1, round((begin + step.seconds) * self._fps))
        for index in range(first, last):
            observation = self.scene.observe(index)
            boxes, keypoints = [], []
            for k in range(self.scene.num_cameras):
                seen = np.isfinite(observation.boxes[:, k]).all(axis=-1)
                boxes.append(observation.boxes[seen, k])
                keypoints.append(observation.keypoints[seen, k])
            yield FeedFrame(index / self._fps, boxes, keypoints)
