"""The CMC bench's oracles (bench/real/cmc_chain.py) on a hand-made frame: the true
association groups each person's boxes and drops the boxes of nobody; the people-only replay
keeps exactly the owned boxes."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.real.cmc_chain import Ground, TrueAssociation
from bench.real.cmc_data import Truth
from models.data.detections_replay import DetectionsReplay
from models.detector.base import Detections
from tests.service.mom_doubles import ModelDouble


class CentreRuntime(ModelDouble):
    """A stand-in model: the floor point is the mean box centre over the seen cameras / 100."""

    num_cameras = 2
    image_sizes = np.array([[640, 480], [640, 480]])

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        centres = 0.5 * (boxes[..., :2] + boxes[..., 2:])
        return np.nanmean(centres, axis=1) / 100.0

    def reprojection_error(
        self, boxes: np.ndarray, world: np.ndarray, keypoints: np.ndarray | None = None
    ) -> np.ndarray:
        return np.where(np.isfinite(boxes[..., 0]), 0.0, np.nan)


def ground() -> Ground:
    # frame 7: person 5 in both cameras, person 6 in camera 1 only, one box of nobody in camera 0
    boxes = np.array([[0, 0, 100, 200], [300, 0, 400, 200], [0, 0, 100, 200], [500, 0, 600, 200]])
    replay = DetectionsReplay(
        frame=np.array([7, 7, 7, 7]),
        camera=np.array([0, 0, 1, 1]),
        boxes=boxes.astype(float),
        scores=np.ones(4),
        image_size=np.array([[640, 480], [640, 480]]),
        fps=4.0,
    )
    truth = Truth(
        np.array([7, 7]), np.array([5, 6]), np.array([[0.5, 1.0], [5.5, 1.0]]), np.ones(2)
    )
    owner = {(7, 0): np.array([5, -1]), (7, 1): np.array([5, 6])}
    return Ground(truth, replay, owner, np.array([7]), np.zeros((2, 3, 4)))


def test_true_association_groups_each_persons_boxes() -> None:
    g = ground()
    oracle = TrueAssociation(g)
    oracle.frame = 7
    detections = [Detections(*g.replay.at(7, k), None) for k in range(2)]
    found = oracle(detections, CentreRuntime(), max_error_px=100.0)
    assert [a.detection_index for a in found] == [[0, 0], [None, 1]]
    assert [a.cameras for a in found] == [[0, 1], [1]]
    np.testing.assert_allclose([a.world for a in found], [[0.5, 1.0], [5.5, 1.0]])
    np.testing.assert_array_equal(g.views(7), [2, 1])
    oracle.frame = 8
    assert oracle(detections, CentreRuntime(), max_error_px=100.0) == []


def test_people_replay_keeps_the_owned_boxes(tmp_path: Path) -> None:
    kept = DetectionsReplay.load(ground().people_replay(tmp_path / "p.npz"))
    assert kept.n == 3
    np.testing.assert_allclose(kept.at(7, 0)[0], [[0, 0, 100, 200]])
    assert len(kept.at(7, 1)[0]) == 2
