"""Association across cameras: oracle-runtime geometry tests and one real trained MoM model."""

from __future__ import annotations

import numpy as np
import pytest

from models.errors import MomlocError
from service.association import associate
from tests.service.mom_doubles import OracleRuntime, person_boxes, room_cameras


def shuffled_detections(
    boxes: np.ndarray, rng: np.random.Generator
) -> tuple[list[np.ndarray], list[list[int]]]:
    """Per camera: the visible boxes in random order, and the true person of each."""
    detections, owners = [], []
    for k in range(boxes.shape[1]):
        people = [i for i in range(len(boxes)) if np.isfinite(boxes[i, k]).all()]
        people = [people[j] for j in rng.permutation(len(people))]
        detections.append(boxes[people, k].reshape(-1, 4).astype(np.float32))
        owners.append(people)
    return detections, owners


def correctly_associated(associations, owners: list[list[int]], boxes: np.ndarray) -> bool:
    """Every output is one person's complete set of visible boxes, and everyone is output."""
    found = {}
    for a in associations:
        ids = {owners[k][j] for k, j in enumerate(a.detection_index) if j is not None}
        if len(ids) != 1:
            return False
        person = ids.pop()
        if person in found:
            return False
        found[person] = sorted(a.cameras)
    expected = {
        i: [k for k in range(boxes.shape[1]) if np.isfinite(boxes[i, k]).all()]
        for i in range(len(boxes))
        if np.isfinite(boxes[i]).all(axis=1).any()
    }
    return found == expected


def random_people(rng: np.random.Generator, count: int, min_gap: float = 0.7) -> np.ndarray:
    while True:
        world = rng.uniform(1.0, 5.0, (count, 2))
        gaps = np.linalg.norm(world[:, None] - world[None], axis=2) + np.eye(count) * 9
        if gaps.min() >= min_gap:
            return world


def test_two_cameras_three_people_shuffled_with_box_noise() -> None:
    rng = np.random.default_rng(0)
    projections = room_cameras(2)
    runtime = OracleRuntime(projections)
    correct = 0
    for _ in range(40):
        world = random_people(rng, 3)
        boxes = person_boxes(projections, world) + rng.normal(0, 2.0, (3, 2, 4))
        detections, owners = shuffled_detections(boxes, rng)
        result = associate(detections, runtime)
        correct += correctly_associated(result, owners, boxes)
        for a in result:
            assert a.boxes.shape == (2, 4) and a.world.shape == (2,)
            assert np.isfinite(a.cost)
    assert correct >= 38  # a rare near-degenerate layout may be ambiguous for any method


def test_swapped_pairs_are_rejected_not_just_ranked() -> None:
    """The exact scene, unshuffled, gives the identity pairing and the true positions."""
    projections = room_cameras(2)
    world = np.array([[2.0, 3.0], [4.0, 1.5], [3.5, 4.5]])
    boxes = person_boxes(projections, world)
    result = associate([boxes[:, 0], boxes[::-1, 1]], OracleRuntime(projections))
    pairs = sorted((a.detection_index[0], a.detection_index[1]) for a in result)
    assert pairs == [(0, 2), (1, 1), (2, 0)]
    for a in result:
        assert np.linalg.norm(a.world - world[a.detection_index[0]]) < 0.05
        assert a.cost < 5.0


def test_four_cameras_with_missing_views() -> None:
    rng = np.random.default_rng(3)
    projections = room_cameras(4)
    runtime = OracleRuntime(projections)
    for _ in range(10):
        world = random_people(rng, 4)
        boxes = person_boxes(projections, world) + rng.normal(0, 1.5, (4, 4, 4))
        boxes[0, [1, 2]] = np.nan  # person 0 seen by cameras 0 and 3 only
        boxes[1, 0] = np.nan  # person 1 missed by camera 0: joined at a later camera
        boxes[2, [0, 1, 3]] = np.nan  # person 2 seen by camera 2 only
        detections, owners = shuffled_detections(boxes, rng)
        result = associate(detections, runtime)
        assert correctly_associated(result, owners, boxes)
        single = [a for a in result if a.cameras == [2] and owners[2][a.detection_index[2]] == 2]
        assert len(single) == 1
        assert np.linalg.norm(single[0].world - world[2]) < 0.2


def test_inconsistent_boxes_stay_separate_people() -> None:
    """One box per camera but of different people: the gate refuses to merge them."""
    projections = room_cameras(2)
    boxes = person_boxes(projections, np.array([[1.5, 4.5], [4.5, 1.5]]))
    result = associate([boxes[:1, 0], boxes[1:, 1]], OracleRuntime(projections))
    assert sorted(a.cameras for a in result) == [[0], [1]]
    # The same pair with a generous gate is merged: the gate, not luck, separated them.
    merged = associate([boxes[:1, 0], boxes[1:, 1]], OracleRuntime(projections), 1e6)
    assert [a.cameras for a in merged] == [[0, 1]]


def test_empty_and_invalid_inputs() -> None:
    runtime = OracleRuntime(room_cameras(2))
    assert associate([np.zeros((0, 4)), np.zeros((0, 4))], runtime) == []
    with pytest.raises(MomlocError, match="2"):
        associate([np.zeros((0, 4))], runtime)
    with pytest.raises(MomlocError, match="camera 1"):
        associate([np.zeros((0, 4)), np.zeros((2, 3))], runtime)
