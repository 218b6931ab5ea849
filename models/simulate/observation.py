"""What one frame of a synthetic scene holds: the truth and what each camera's detector reports.

Kept apart from :mod:`models.simulate.scene` (which computes it) because every consumer reads
it: the live simulated detector, the set-up feed, the stream evaluation and the benchmarks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

OBSERVED = (
    "world", "joints", "boxes", "keypoints", "true_boxes", "false_boxes", "outside_world",
    "outside_boxes", "outside_keypoints", "outside_true_boxes",
)  # fmt: skip


@dataclass(frozen=True)
class FrameObservation:
    """One frame: ``track`` [P], ``world`` [P,2], ``joints`` [P,17,3] (world metres),
    ``boxes`` [P,K,4] noisy (NaN: not detected), ``keypoints`` [P,K,17,3], ``true_boxes``
    [P,K,4] (tight, unclipped box of the projected body; NaN behind the camera or off-image),
    ``false_boxes`` [K,Q,4] the detector's false positives per camera (NaN-padded; no person).

    People outside the set-up area (``SceneConfig.outside_people``, O of them) are not in
    ``track``/``world``/``boxes``: ``outside_world`` [O,2], ``outside_boxes`` [O,K,4] (noisy,
    NaN: not detected), ``outside_keypoints`` [O,K,17,3] and ``outside_true_boxes`` [O,K,4] hold
    them (O = 0 without outside people). The detector reports their boxes like anyone's."""

    frame: int
    track: np.ndarray
    world: np.ndarray
    joints: np.ndarray
    boxes: np.ndarray
    keypoints: np.ndarray
    true_boxes: np.ndarray
    false_boxes: np.ndarray
    outside_world: np.ndarray
    outside_boxes: np.ndarray
    outside_keypoints: np.ndarray
    outside_true_boxes: np.ndarray

    def reported(self, camera: int) -> tuple[np.ndarray, np.ndarray]:
        """What camera ``camera``'s detector reports: boxes [M, 4] (the people it found, then
        the outside people it found, then its false positives; :meth:`reported_outside` says
        which are outside people) and their keypoints [M, 17, 3], NaN for a false box (a pose
        estimator finding no body in it). What the live simulated detector
        (``service.detection.simulated``), the set-up feed (``service.setup.feeds``) and the
        stream evaluation (``service.offline.stream_eval``) read; some benchmarks
        (``bench.serving.stream_bound``,
        ``bench.serving.association``, ``bench.serving.realtime``) read ``boxes`` directly instead,
        without the false positives."""
        seen = np.isfinite(self.boxes[:, camera]).all(axis=-1)
        out = np.isfinite(self.outside_boxes[:, camera]).all(axis=-1)
        false = self.false_boxes[camera]
        false = false[np.isfinite(false).all(axis=-1)]
        joints = self.keypoints.shape[2:]
        boxes = np.concatenate([self.boxes[seen, camera], self.outside_boxes[out, camera], false])
        points = np.concatenate(
            [
                self.keypoints[seen, camera],
                self.outside_keypoints[out, camera],
                np.full((len(false), *joints), np.nan),
            ]
        )
        return boxes, points

    def reported_outside(self, camera: int) -> np.ndarray:
        """[M] bool over :meth:`reported`'s boxes: True for a person outside the set-up area."""
        seen = int(np.isfinite(self.boxes[:, camera]).all(axis=-1).sum())
        out = int(np.isfinite(self.outside_boxes[:, camera]).all(axis=-1).sum())
        false = int(np.isfinite(self.false_boxes[camera]).all(axis=-1).sum())
        return np.repeat([False, True, False], [seen, out, false])
