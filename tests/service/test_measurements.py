"""Measurement noise and coverage from the model, and the live pipeline feeding them to the tracker.

The pipeline tests run the real association, tracker and measurement code on the oracle runtime
(true projections, no covariance of its own, so the per-view-class defaults apply): one camera
first sees a person with its range wrong by 0.5 m, then the second camera joins.
"""

from __future__ import annotations

import numpy as np
import pytest

from capture.rig import FrameSet
from models.detector.base import Detections
from models.mom.setup_area import SetupArea
from service.pipeline.hub import Hub
from service.pipeline.live import Pipeline
from service.stages import Association
from service.tracking.measurements import (
    MULTI_VIEW_STD_M,
    SINGLE_VIEW_ACROSS_STD_M,
    SINGLE_VIEW_DEPTH_STD_M,
    coverage_function,
    default_covariance,
    measurement_covariances,
)
from service.tracking.tracker import RECOMMENDED, Tracker
from service.tracking.view_geometry import covering_cameras, floor_pixels, line_of_sight
from tests.service.fake_frames import FunctionStage, NoRig, frames_at
from tests.service.mom_doubles import ModelDouble, OracleRuntime, person_boxes, room_cameras

CAMERAS = room_cameras(2)  # corners (-0.5, -0.5) and (6.5, -0.5), 2.4 m high
TRUTH = np.array([3.0, 2.0])
FPS = 30.0


def test_line_of_sight_points_from_the_camera_to_the_person():
    runtime = OracleRuntime(CAMERAS)
    for k, camera_xy in enumerate(([-0.5, -0.5], [6.5, -0.5])):
        expected = TRUTH - np.array(camera_xy)
        expected /= np.linalg.norm(expected)
        assert abs(float(line_of_sight(runtime, k, TRUTH) @ expected)) == pytest.approx(1, abs=1e-3)


def _with_heights(runtime: OracleRuntime) -> OracleRuntime:
    """The oracle runtime with a set-up area fitted on standing people over the room."""
    grid = np.stack(np.meshgrid(np.linspace(0.5, 5.5, 11), np.linspace(0.5, 5.5, 11)), -1)
    grid = grid.reshape(-1, 2)
    runtime.setup_area = SetupArea.fit(grid, person_boxes(runtime.projections, grid))  # type: ignore[attr-defined]
    return runtime


def test_the_floor_pixel_is_the_bottom_of_a_standing_person_s_box() -> None:
    runtime = _with_heights(OracleRuntime(CAMERAS))
    world = np.array([[3.0, 3.0], [4.8, 1.2], [1.5, 2.5]])
    boxes = person_boxes(CAMERAS, world)
    floor = floor_pixels(runtime, world)
    height = boxes[..., 3] - boxes[..., 1]
    assert (np.abs(floor[..., 1] - boxes[..., 3]) < 0.05 * height).all()
    assert np.allclose(floor[..., 0], runtime.reproject(world)[..., 0])


def test_a_camera_beside_a_body_on_the_floor_does_not_cover_it() -> None:
    """1.9 m in front of camera 1 a standing person's upper body is in its image and the floor
    under them is below it: a lying body there is camera 0's alone to see."""
    runtime = _with_heights(OracleRuntime(CAMERAS))
    world = np.array([[4.8, 1.2], [3.0, 3.0]])
    assert covering_cameras(runtime, world).tolist() == [[True, True], [True, True]]
    lying = covering_cameras(runtime, world, lying=np.array([True, True]))
    assert lying.tolist() == [[True, False], [True, True]]
    coverage = coverage_function(runtime, [True, False])
    assert coverage is not None
    assert coverage(world, np.array([True, False])).tolist() == [[True, False], [True, False]]


def test_default_covariance_per_view_class():
    runtime = OracleRuntime(CAMERAS)
    single = default_covariance(runtime, [0], TRUTH)
    along = line_of_sight(runtime, 0, TRUTH)
    assert single is not None and along is not None
    across = np.array([-along[1], along[0]])
    assert along @ single @ along == pytest.approx(SINGLE_VIEW_DEPTH_STD_M**2)
    assert across @ single @ across == pytest.approx(SINGLE_VIEW_ACROSS_STD_M**2)
    both = default_covariance(runtime, [0, 1], TRUTH)
    assert both is not None
    np.testing.assert_allclose(both, np.eye(2) * MULTI_VIEW_STD_M**2)
    nowhere = ModelDouble()  # its decoder puts nobody in an image: no line of sight
    nowhere.num_cameras = 2
    assert default_covariance(nowhere, [0], TRUTH) is None


def test_the_models_own_covariance_wins_when_finite():
    runtime = OracleRuntime(CAMERAS)
    own = np.diag([0.04, 0.01])
    people = [
        _seen_by([0], covariance=own),
        _seen_by([0], covariance=np.full((2, 2), np.nan)),
        _seen_by([0, 1], covariance=None),  # none given
    ]
    first, second, third = measurement_covariances(people, runtime)
    default = default_covariance(runtime, [0], TRUTH)
    assert first is not None and second is not None and third is not None
    assert default is not None
    np.testing.assert_array_equal(first, own)
    np.testing.assert_allclose(second, default)
    np.testing.assert_allclose(third, np.eye(2) * MULTI_VIEW_STD_M**2)


def test_coverage_leaves_out_cameras_without_a_frame():
    runtime = OracleRuntime(CAMERAS)
    every, first_only = (
        coverage_function(runtime, [True, True]),
        coverage_function(runtime, [True, False]),
    )
    assert every is not None and first_only is not None
    assert every(TRUTH[None]).tolist() == [[True, True]]
    assert first_only(TRUTH[None]).tolist() == [[True, False]]
    assert coverage_function(None, [True, True]) is None


def _seen_by(cameras: list[int], covariance: np.ndarray | None) -> Association:
    boxes = np.full((2, 4), np.nan, np.float32)
    index: list[int | None] = [0 if k in cameras else None for k in (0, 1)]
    return Association(boxes, cameras, TRUTH, 0.0, index, covariance=covariance)


def _serve(*, lone_frames: int, joined_frames: int, camera1_delivers: bool, wired: bool = True):
    """Served distance to the truth (None: nobody served) per frame from the last lone one on.

    Camera 0 alone sees the person 0.5 m too far along its line of sight for ``lone_frames``;
    camera 1 meanwhile delivers empty frames (``camera1_delivers``) or none at all. Then both
    see the person where they are. ``wired=False`` drops the covariances and coverage before
    they reach the tracker (what the pipeline did before they were wired)."""
    runtime = OracleRuntime(CAMERAS)
    sight = line_of_sight(runtime, 0, TRUTH)
    assert sight is not None
    wrong = TRUTH + 0.5 * sight

    def frames(i: int) -> FrameSet:
        return frames_at(i, 100 + i / FPS, (True, camera1_delivers or i >= lone_frames))

    def detect(frame_set: FrameSet) -> list[Detections]:
        first = frame_set.frames[0]
        assert first is not None
        if first.seq < lone_frames:
            lone = person_boxes(CAMERAS, wrong[None])[0, 0]
            return [_found(lone[None]), Detections.empty()]
        both = person_boxes(CAMERAS, TRUTH[None])[0]
        return [_found(both[0][None]), _found(both[1][None])]

    tracker = Tracker(fps_hint=FPS, **RECOMMENDED)
    if not wired:
        update = tracker.update
        tracker.update = lambda t, xy, origins, **_: update(t, xy, origins)  # type: ignore[method-assign]
    pipeline = Pipeline(
        NoRig(), FunctionStage(detect), Hub(), num_cameras=2, runtime=runtime, tracker=tracker,
        shift_threaded=False,
    )  # fmt: skip
    out = []
    try:
        for i in range(lone_frames + joined_frames):
            people = pipeline.process(frames(i)).people
            if i >= lone_frames - 1:
                xy = [np.hypot(p["x"] - TRUTH[0], p["y"] - TRUTH[1]) for p in people]
                out.append(min(xy) if xy else None)
    finally:
        pipeline.stop()
    return out


def test_a_second_camera_corrects_a_lone_views_range_at_once():
    """The lone view's covariance is long along its line of sight, so the first two-view
    positions pull the track there at once; with the isotropic default they are averaged in."""
    wired = _serve(lone_frames=45, joined_frames=3, camera1_delivers=False)
    plain = _serve(lone_frames=45, joined_frames=3, camera1_delivers=False, wired=False)
    assert wired[0] == pytest.approx(0.5, abs=0.05) and plain[0] == pytest.approx(0.5, abs=0.05)
    assert wired[-1] < 0.15, wired  # measured 0.09 m after 3 frames (0.1 s)
    assert plain[-1] > 0.35, plain  # measured 0.45 m


def test_a_lone_view_another_delivering_camera_should_see_is_not_served():
    """Coverage reaches the tracker: camera 1 delivers frames, covers the place and reports
    nothing, so camera 0's lone box is a ghost; with camera 1 delivering no frames it is not."""
    doubted = _serve(lone_frames=45, joined_frames=1, camera1_delivers=True)
    believed = _serve(lone_frames=45, joined_frames=1, camera1_delivers=False)
    assert doubted[0] is None and believed[0] is not None


def _found(boxes: np.ndarray) -> Detections:
    return Detections(boxes.astype(np.float32), np.ones(len(boxes), np.float32))
