"""Association across cameras: oracle-runtime geometry tests and one real trained MoM model."""

from __future__ import annotations

import numpy as np
import pytest

from common.errors import MomlocError
from service.stages import Association
from service.tracking.association import (
    DEFAULT_MAX_ERROR_PX,
    DEFAULT_MAX_VIEW_GAP_M,
    FLOOR_INFO_SCALE,
    associate,
)
from tests.service.mom_doubles import ModelDouble, OracleRuntime, person_boxes, room_cameras


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
        # The oracle's errors are ~2 px, so a tight gate suits it; the default (100, sized for a
        # learned model's noise) would let the lone camera-2 box of person 2 join person 0
        # when they stand within ~0.8 m: that trade-off is measured in bench/serving/association.py.
        result = associate(detections, runtime, max_error_px=25.0)
        assert correctly_associated(result, owners, boxes)
        single = [a for a in result if a.cameras == [2] and owners[2][_index(a, 2)] == 2]
        assert len(single) == 1
        assert np.linalg.norm(single[0].world - world[2]) < 0.2


def test_inconsistent_boxes_stay_separate_people() -> None:
    """One box per camera but of different people (4.2 m apart): each gate alone refuses."""
    projections = room_cameras(2)
    boxes = person_boxes(projections, np.array([[1.5, 4.5], [4.5, 1.5]]))
    detections = [boxes[:1, 0], boxes[1:, 1]]
    runtime = OracleRuntime(projections)

    def cameras(
        max_error_px: float = DEFAULT_MAX_ERROR_PX, max_view_gap_m: float = DEFAULT_MAX_VIEW_GAP_M
    ) -> list[list[int]]:
        found = associate(detections, runtime, max_error_px, max_view_gap_m)
        return sorted(a.cameras for a in found)

    assert cameras() == [[0], [1]]
    assert cameras(max_error_px=1e6) == [[0], [1]]  # the single views disagree by 4.2 m
    assert cameras(max_error_px=25.0, max_view_gap_m=1e6) == [[0], [1]]  # reprojection
    # With both gates open the pair is merged: the gates, not luck, separated them.
    assert cameras(max_error_px=1e6, max_view_gap_m=1e6) == [[0, 1]]


class ScriptedRuntime(ModelDouble):
    """Two cameras; box j is ``[j, 0, j + 1, 200]`` (reference height: errors are not rescaled);
    pair errors come from a table."""

    num_cameras = 2
    image_sizes = np.array([[640, 480], [640, 480]])

    def __init__(self, pair_error: dict[tuple[int, int], float]) -> None:
        self.pair_error = pair_error

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        # "world" = (index in cam 0, index in cam 1); every single view at (-1, -1)
        both = np.isfinite(boxes[:, :, 0]).all(axis=1)
        return np.where(both[:, None], np.nan_to_num(boxes[:, :, 0]), -1.0)

    def reprojection_error(
        self, boxes: np.ndarray, world: np.ndarray, keypoints: np.ndarray | None = None
    ) -> np.ndarray:
        out = np.where(np.isfinite(boxes).all(axis=2), 0.0, np.nan)
        for b, (i, j) in enumerate(world.astype(int)):
            if i >= 0 and j >= 0:
                out[b] = self.pair_error[(i, j)]
        return out


def test_two_marginal_pairs_do_not_beat_one_good_pair() -> None:
    """Camera 0 sees A, B; camera 1 sees A, C. B+A and A+C pass the gate but are wrong."""
    boxes = np.array([[j, 0, j + 1, 200] for j in range(2)], dtype=np.float32)
    table = {(0, 0): 5.0, (0, 1): 30.0, (1, 0): 30.0, (1, 1): 90.0}
    result = associate([boxes, boxes], ScriptedRuntime(table), max_error_px=40.0)
    assert sorted(map(str, (a.detection_index for a in result))) == [
        "[0, 0]",
        "[1, None]",
        "[None, 1]",
    ]
    # Pairs are only made below the gate, and a clearly better pairing wins.
    table = {(0, 0): 35.0, (0, 1): 3.0, (1, 0): 4.0, (1, 1): 35.0}
    result = associate([boxes, boxes], ScriptedRuntime(table), max_error_px=40.0)
    assert sorted(a.detection_index for a in result) == [[0, 1], [1, 0]]


def test_single_camera_model_outputs_every_box() -> None:
    projections = room_cameras(1)
    world = np.array([[2.0, 2.0], [4.0, 3.0], [3.0, 5.0]])
    boxes = person_boxes(projections, world)[:, 0]
    result = associate([boxes], OracleRuntime(projections))
    assert sorted(_index(a, 0) for a in result) == [0, 1, 2]
    for a in result:
        assert a.cameras == [0]
        assert np.linalg.norm(a.world - world[a.detection_index[0]]) < 0.05


def test_empty_and_invalid_inputs() -> None:
    runtime = OracleRuntime(room_cameras(2))
    assert associate([np.zeros((0, 4)), np.zeros((0, 4))], runtime) == []
    with pytest.raises(MomlocError, match="2"):
        associate([np.zeros((0, 4))], runtime)
    with pytest.raises(MomlocError, match="camera 1"):
        associate([np.zeros((0, 4)), np.zeros((2, 3))], runtime)


@pytest.fixture(scope="session")
def trained_runtime(tmp_path_factory: pytest.TempPathFactory):
    """A small real MoM model (indoor-2cam), trained once per test session.

    Pinned to the ``ideal`` detector profile (the former kind noise) on purpose: these tests
    check the association algorithm with a real model, not the detector; what the measured
    detector costs association is in ``bench/serving/association.py``. (Measured 2026-12-01 with
    this model and test: ideal 54/60 frames right, median 0.093 m; nanodet 47/59, 0.357 m.)
    """
    from models.mom.runtime import MomRuntime
    from models.mom.training.train import train_model
    from models.simulate import simulate

    out = tmp_path_factory.mktemp("assoc-model")
    data = simulate("indoor-2cam", frames=500, seed=11, detector_profile="ideal").dataset
    train_model(data, out, epochs=20, progress=False)
    return MomRuntime.load(out)


def test_real_model_associates_three_people(trained_runtime) -> None:
    from models.simulate import Scene, get_config

    # not the training recording; kind noise, see `trained_runtime`
    scene = Scene(get_config("indoor-2cam", people=3, detector_profile="ideal"), seed=5)
    rng = np.random.default_rng(0)
    frames = correct = 0
    errors = []
    for i in range(0, 240, 4):
        obs = scene.observe(i)
        if not np.isfinite(obs.boxes).all(axis=2).any():
            continue
        detections, owners = shuffled_detections(obs.boxes, rng)
        result = associate(detections, trained_runtime)
        frames += 1
        ok = correctly_associated(result, owners, obs.boxes)
        correct += ok
        if ok:
            for a in result:
                person = owners[a.cameras[0]][_index(a, a.cameras[0])]
                errors.append(np.linalg.norm(a.world - obs.world[person]))
    assert frames >= 50
    # A tiny 20-epoch model: measured 52/60 (87 %); the bench's full model reaches > 99 %.
    assert correct / frames >= 0.8
    assert np.median(errors) < 0.35


def test_one_association_gate_default_everywhere() -> None:
    import inspect

    from service.offline.stream_eval import run_stream
    from service.pipeline.live import Pipeline
    from service.settings import TrackingSettings
    from service.tracking.association import DEFAULT_MAX_ERROR_PX

    assert TrackingSettings().max_error_px == DEFAULT_MAX_ERROR_PX
    for function in (associate, Pipeline, run_stream):
        default = inspect.signature(function).parameters["max_error_px"].default
        assert default == DEFAULT_MAX_ERROR_PX, function


class KeypointOracle(OracleRuntime):
    """The oracle reading keypoints instead of boxes: one keypoint per view at the body's
    mid-height point (what the box centre is for the box oracle)."""

    observation = "keypoints"

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        assert keypoints is not None, "a keypoint model must be given keypoints"
        return super().localize(_point_boxes(keypoints))

    def reprojection_error(self, boxes, world, keypoints=None) -> np.ndarray:
        assert keypoints is not None, "a keypoint model must be given keypoints"
        return super().reprojection_error(_point_boxes(keypoints), world)


def _point_boxes(keypoints: np.ndarray) -> np.ndarray:
    """Zero-size boxes at each view's (single) keypoint, NaN where unseen."""
    xy = np.asarray(keypoints, np.float64)[..., 0, :2]
    return np.concatenate([xy, xy], axis=-1)


def test_keypoint_models_associate_and_localize_from_keypoints():
    """Boxes that lie (each person's box swapped with another's) but keypoints that are right:
    a keypoint model must follow the keypoints, through association and localization."""
    from models.detector.base import Detections

    projections = room_cameras(2)
    world = np.array([[1.5, 2.0], [4.0, 4.5], [2.5, 4.0]])
    boxes = person_boxes(projections, world).astype(np.float32)
    centres = (boxes[..., :2] + boxes[..., 2:]) / 2
    runtime = KeypointOracle(projections)
    detections = []
    for k in range(2):
        points = np.concatenate([centres[:, k], np.ones((3, 1), np.float32)], axis=1)
        lying = np.roll(boxes[:, k], 1, axis=0)  # person i gets person i-1's box
        detections.append(Detections(lying, np.ones(3, np.float32), points[:, None, :]))
    associations = associate(detections, runtime)
    assert len(associations) == 3
    for a in associations:
        assert a.detection_index[0] == a.detection_index[1]  # the same person in both views
        person = a.detection_index[0]
        # box-centre oracle: centimetres off; the lying boxes would put it metres off
        np.testing.assert_allclose(a.world, world[person], atol=0.05)
        assert a.keypoints is not None and a.keypoints.shape == (2, 1, 3)
    with pytest.raises(MomlocError, match="keypoints"):
        associate([d.boxes for d in detections], runtime)  # boxes only: refused, one line


def test_floor_gate_cost_is_the_mahalanobis_rise_of_the_fused_position() -> None:
    """Each box on the floor by its own camera (long along that camera's line of sight); the
    cost of merging two clusters is d^T (C_P + C_Q)^-1 d between their fused positions
    (information scaled for the prior's overconfidence), NaN where a side has no floor
    information. Two crossing views fix a point; a third view agrees with it only where its
    line of sight passes through it."""
    from service.tracking.association import _FloorFit, _Views

    along_x = np.diag([1.0**2, 0.05**2])  # cameras 0 and 2 know y well, x badly
    along_y = np.diag([0.05**2, 1.0**2])  # camera 1 the other way round
    rows = [(0, [1.0, 2.0], along_x), (1, [2.0, 1.2], along_y)]
    rows += [(2, [1.5, 2.0], along_x), (2, [2.0, 3.5], along_x)]  # camera 2: y agrees / 1.5 m off
    est = np.zeros((len(rows), 3, 2))
    info = np.zeros((len(rows), 3, 2, 2))
    for r, (k, xy, cov) in enumerate(rows):
        est[r, k], info[r, k] = xy, np.linalg.inv(cov)

    class Floor:
        num_cameras = 3
        image_sizes = np.array([[640, 480]] * 3)
        observation = "bbox"

        def floor_views(self, boxes, keypoints=None):
            return est, info

    box = np.array([[10, 10, 50, 200]], np.float32)
    views = _Views([box, box, np.r_[box, box]], None)
    pair = {0: 0, 1: 0}
    cost = _FloorFit(views, Floor()).chi2([(pair, {2: 0}), (pair, {2: 1})])
    assert cost is not None
    scale = FLOOR_INFO_SCALE**2
    lam = np.linalg.inv(along_x * scale) + np.linalg.inv(along_y * scale)
    fused = np.linalg.solve(lam, np.linalg.inv(along_x * scale) @ est[0, 0]
                            + np.linalg.inv(along_y * scale) @ est[1, 1])  # fmt: skip
    for r, got in zip((2, 3), cost, strict=True):
        d = fused - est[r, 2]
        assert got == pytest.approx(d @ np.linalg.solve(np.linalg.inv(lam) + along_x * scale, d))
    assert cost[0] < 1.0 < 25.0 < cost[1]  # the default gate admits the first, not the second
    info[3, 2] = 0.0  # a camera without a floor map: no veto
    vetoless = _FloorFit(views, Floor()).chi2([(pair, {2: 1})])
    assert vetoless is not None and np.isnan(vetoless[0])


def _index(association: Association, camera: int) -> int:
    """The index of ``association``'s detection in ``camera`` (which sees it)."""
    index = association.detection_index[camera]
    assert index is not None
    return index


class FloorOracle(OracleRuntime):
    """An oracle with per-camera floor maps: each box alone on the floor, known to
    ``ACROSS_M`` across its camera's line of sight and ``ALONG_M`` along it."""

    ACROSS_M, ALONG_M = 0.02, 0.6

    def floor_views(self, boxes, keypoints=None):
        boxes = np.asarray(boxes, np.float64)
        est = np.full((*boxes.shape[:2], 2), np.nan)
        info = np.zeros((*boxes.shape[:2], 2, 2))
        for b, k in zip(*np.nonzero(np.isfinite(boxes).all(axis=2)), strict=True):
            alone = np.full_like(boxes[:1], np.nan)
            alone[0, k] = boxes[b, k]
            est[b, k] = self.localize(alone)[0]
            centre = np.linalg.svd(self.projections[k])[2][-1]
            sight = est[b, k] - centre[:2] / centre[3]
            along = sight / np.linalg.norm(sight)
            turn = np.column_stack([along, [-along[1], along[0]]])
            info[b, k] = np.linalg.inv(turn @ np.diag([self.ALONG_M, self.ACROSS_M]) ** 2 @ turn.T)
        return est, info


def test_tracked_people_absorb_their_fragments() -> None:
    """Track-driven association: a person whose third camera's box is off sideways (a cut box:
    the floor maps disagree beyond the merge gate) is split into two clusters by the boxes
    alone; with their track's prediction the lone box joins the main cluster. A neighbour's
    track keeps its own cluster, and an anchor near no box changes nothing."""
    from service.stages import TrackAnchor

    runtime = FloorOracle(room_cameras(3))
    world = np.array([[3.0, 3.0], [4.6, 3.0]])
    boxes = person_boxes(runtime.projections, world)
    boxes[0, 2, [0, 2]] += 60.0  # camera 2 sees person 0's box shifted sideways
    detections = [boxes[:, k].astype(np.float32) for k in range(3)]

    alone = associate(detections, runtime)
    assert sorted(len(a.cameras) for a in alone) == [1, 2, 3]  # person 0 split in two

    anchors = [TrackAnchor(xy, np.eye(2) * 0.3**2) for xy in world]
    tracked = associate(detections, runtime, anchors=anchors)
    assert len(tracked) == 2
    for a in tracked:
        assert a.cameras == [0, 1, 2]
        assert len({a.detection_index[k] for k in range(3)}) == 1  # one person's boxes
    nowhere = [TrackAnchor(np.array([0.5, 5.5]), np.eye(2) * 0.01)]
    far = associate(detections, runtime, anchors=nowhere)
    assert [a.detection_index for a in far] == [a.detection_index for a in alone]


@pytest.mark.parametrize("cameras", [2, 3])
def test_a_box_continuing_another_track_in_its_image_is_not_joined(cameras: int) -> None:
    """Per-camera box continuity vetoes a mix the floor cannot see: two neighbours, camera 1
    sees one box, which lies where person 0 should be (floor and reprojection pair it with
    person 0's box of camera 0), but in camera 1's own image it continues track 1's box.
    With the tracks' image predictions it joins no box of track 0 (neither in the clustering
    nor as a fragment folded into track 0's cluster); without them (or with the veto off,
    the default) the boxes alone mix."""
    from service.stages import TrackAnchor

    runtime = FloorOracle(room_cameras(cameras))
    world = np.array([[3.0, 3.0], [3.5, 3.0]])
    boxes = person_boxes(runtime.projections, world)
    detections = [boxes[:, 0].astype(np.float32), boxes[:1, 1].astype(np.float32)]
    detections += [boxes[1:, k].astype(np.float32) for k in range(2, cameras)]
    centre = [0.5 * (d[:, 0] + d[:, 2]) for d in detections]
    image_x = [np.full(cameras, np.nan) for _ in world]
    image_x[0][0], image_x[1][0], image_x[1][1] = centre[0][0], centre[0][1], centre[1][0]
    std = np.full(cameras, 3.0)
    anchors = [TrackAnchor(xy, np.eye(2) * 0.3**2) for xy in world]

    def joined(found: list[Association]) -> bool:
        return any(a.detection_index[:2] == [0, 0] for a in found)

    assert joined(associate(detections, runtime))
    assert joined(associate(detections, runtime, anchors=anchors, continuity_z2=4.0))
    continued = [TrackAnchor(a.xy, a.cov, x, std) for a, x in zip(anchors, image_x, strict=True)]
    found = associate(detections, runtime, anchors=continued, continuity_z2=4.0)
    assert not joined(found)
    assert any(a.detection_index[1] == 0 for a in found)  # the box is kept, not dropped
    assert joined(associate(detections, runtime, anchors=continued))  # off by default


class LoneViewRuntime(ModelDouble):
    """Two cameras; camera k's box j is ``[j, 0, j + 1, 200]`` and lands alone at
    ``lone[k][j]``, known to ``ACROSS_M`` across that camera's line of sight (``sight[k]``) and
    ``along[k][j]`` along it (a far view's range is known worse); a tuple lands at the mean of
    its views and reprojects perfectly (only the view gap can refuse a pair)."""

    num_cameras = 2
    image_sizes = np.array([[1920, 1080], [1920, 1080]])
    ACROSS_M = 0.05

    def __init__(
        self, lone: list[list[list[float]]], along: list[list[float]], sight: list[list[float]]
    ) -> None:
        self.lone = [np.asarray(p, np.float64) for p in lone]
        self.along = [np.asarray(s, np.float64) for s in along]
        self.sight = [np.asarray(s, np.float64) / np.linalg.norm(s) for s in sight]

    def _views(self, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        boxes = np.asarray(boxes, np.float64)
        est = np.zeros((len(boxes), 2, 2))
        info = np.zeros((len(boxes), 2, 2, 2))
        for b, k in zip(*np.nonzero(np.isfinite(boxes).all(axis=2)), strict=True):
            j = int(boxes[b, k, 0])
            u = self.sight[k]
            turn = np.column_stack([u, [-u[1], u[0]]])
            cov = turn @ np.diag([self.along[k][j], self.ACROSS_M]) ** 2 @ turn.T
            est[b, k], info[b, k] = self.lone[k][j], np.linalg.inv(cov)
        return est, info

    def localize(self, boxes: np.ndarray, keypoints: np.ndarray | None = None) -> np.ndarray:
        est, info = self._views(boxes)
        seen = np.trace(info, axis1=2, axis2=3) > 0
        return (est * seen[..., None]).sum(axis=1) / seen.sum(axis=1, keepdims=True)

    def reprojection_error(
        self, boxes: np.ndarray, world: np.ndarray, keypoints: np.ndarray | None = None
    ) -> np.ndarray:
        return np.where(np.isfinite(boxes).all(axis=2), 0.0, np.nan)

    def floor_views(self, boxes, keypoints=None):
        return self._views(boxes)


SIGMAS = 4.0  # the scaled view gap as measured on MultiviewX (off by default)


def _joined(runtime: LoneViewRuntime, gap_sigmas: float = SIGMAS) -> bool:
    """Whether the pair's two boxes become one person (only the view gap can refuse them)."""
    box = np.array([[0, 0, 1, 200]], np.float32)
    found = associate([box, box], runtime, max_floor_chi2=np.inf, gap_sigmas=gap_sigmas)
    return sorted(a.cameras for a in found) == [[0, 1]]


def test_view_gap_grows_with_the_views_own_uncertainty() -> None:
    """Camera 0 sees a person near (range known to 5 cm, its line of sight along y); camera 1,
    looking along x, sees them 20 m away, where its lone view's range is off by 2.5 m and known
    to 0.3 m (x3 for the floor maps' overconfidence: 0.9 m). 2.5 m is beyond the fixed 2 m but
    within 4 std of the gap (``SIGMAS``), so the far view joins its person; the same 2.5 m from
    a view whose range is known to 5 cm is a different person and stays apart. Within 2 m every
    pair joins (the fixed radius is the floor); without floor maps the fixed radius alone
    decides."""
    from service.tracking.association import _FloorFit, _Views

    class WithoutFloorMaps(LoneViewRuntime):
        def floor_views(self, boxes, keypoints=None):
            return None

    def runtime(
        offset: float, along: float, kind: type[LoneViewRuntime] = LoneViewRuntime
    ) -> LoneViewRuntime:
        return kind(
            lone=[[[20.0, 0.0]], [[20.0 + offset, 0.0]]],
            along=[[0.05], [along]],
            sight=[[0.0, 1.0], [1.0, 0.0]],
        )

    far = runtime(2.5, 0.3)
    std = np.sqrt(0.05**2 + 0.3**2) * FLOOR_INFO_SCALE  # along the gap (x): across 0, along 1
    box = np.array([[0, 0, 1, 200]], np.float32)
    got = _FloorFit(_Views([box, box], None), far).gap_std([({0: 0}, {1: 0})], np.array([[2.5, 0]]))
    assert got is not None and got[0] == pytest.approx(std)
    assert 2.0 < 2.5 < SIGMAS * std
    assert _joined(far)
    assert not _joined(far, gap_sigmas=0.0)  # the fixed 2 m gate (the default) splits them
    assert not _joined(runtime(2.5, 0.05))  # a near view 2.5 m off: another person
    assert _joined(runtime(1.8, 0.05))  # within the fixed radius
    assert not _joined(runtime(SIGMAS * std + 0.1, 0.3))  # beyond its own spread

    assert not _joined(runtime(2.5, 0.3, WithoutFloorMaps))
    assert _joined(runtime(1.8, 0.3, WithoutFloorMaps))
