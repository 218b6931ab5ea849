"""Measurement noise and coverage from the model, and the live pipeline feeding them to the tracker.

The pipeline tests run the real association, tracker and measurement code on the oracle runtime
(true projections, no covariance of its own, so the per-view-class defaults apply): one camera
first sees a person with its range wrong by 0.5 m, then the second camera joins.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from service.pipeline.hub import Hub
from service.pipeline.live import Pipeline
from service.tracking.measurements import (
    MULTI_VIEW_STD_M,
    SINGLE_VIEW_ACROSS_STD_M,
    SINGLE_VIEW_DEPTH_STD_M,
    coverage_function,
    default_covariance,
    measurement_covariances,
)
from service.tracking.tracker import RECOMMENDED, Tracker
from service.tracking.view_geometry import line_of_sight
from tests.service.mom_doubles import OracleRuntime, person_boxes, room_cameras

CAMERAS = room_cameras(2)  # corners (-0.5, -0.5) and (6.5, -0.5), 2.4 m high
TRUTH = np.array([3.0, 2.0])
FPS = 30.0


def test_line_of_sight_points_from_the_camera_to_the_person():
    runtime = OracleRuntime(CAMERAS)
    for k, camera_xy in enumerate(([-0.5, -0.5], [6.5, -0.5])):
        expected = TRUTH - np.array(camera_xy)
        expected /= np.linalg.norm(expected)
        assert abs(float(line_of_sight(runtime, k, TRUTH) @ expected)) == pytest.approx(1, abs=1e-3)


def test_default_covariance_per_view_class():
    runtime = OracleRuntime(CAMERAS)
    single = default_covariance(runtime, [0], TRUTH)
    along = line_of_sight(runtime, 0, TRUTH)
    across = np.array([-along[1], along[0]])
    assert along @ single @ along == pytest.approx(SINGLE_VIEW_DEPTH_STD_M**2)
    assert across @ single @ across == pytest.approx(SINGLE_VIEW_ACROSS_STD_M**2)
    np.testing.assert_allclose(
        default_covariance(runtime, [0, 1], TRUTH), np.eye(2) * MULTI_VIEW_STD_M**2
    )
    no_decoder = SimpleNamespace(num_cameras=2)  # nothing to find the line of sight with
    assert default_covariance(no_decoder, [0], TRUTH) is None


def test_the_models_own_covariance_wins_when_finite():
    runtime = OracleRuntime(CAMERAS)
    own = np.diag([0.04, 0.01])
    people = [
        SimpleNamespace(cameras=[0], world=TRUTH, covariance=own),
        SimpleNamespace(cameras=[0], world=TRUTH, covariance=np.full((2, 2), np.nan)),
        SimpleNamespace(cameras=[0, 1], world=TRUTH),  # a runtime without covariance()
    ]
    first, second, third = measurement_covariances(people, runtime)
    np.testing.assert_array_equal(first, own)
    np.testing.assert_allclose(second, default_covariance(runtime, [0], TRUTH))
    np.testing.assert_allclose(third, np.eye(2) * MULTI_VIEW_STD_M**2)


def test_coverage_leaves_out_cameras_without_a_frame():
    runtime = OracleRuntime(CAMERAS)
    assert coverage_function(runtime, [True, True])(TRUTH[None]).tolist() == [[True, True]]
    assert coverage_function(runtime, [True, False])(TRUTH[None]).tolist() == [[True, False]]
    assert coverage_function(None, [True, True]) is None
    assert coverage_function(SimpleNamespace(num_cameras=2), [True, True]) is None


class _NoRig:
    def start(self) -> None: ...
    def stop(self) -> None: ...
    def frame_set(self, after=None, timeout=0.0): ...
    def states(self) -> list:
        return []


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

    def frames(i: int) -> SimpleNamespace:
        present = (True, camera1_delivers or i >= lone_frames)
        return SimpleNamespace(
            frames=[
                SimpleNamespace(camera=k, image=None, timestamp=100 + i / FPS, seq=i)
                if on
                else None
                for k, on in enumerate(present)
            ],
            skew=0.0,
        )

    def detect(frame_set) -> list[np.ndarray]:
        if frame_set.frames[0].seq < lone_frames:
            lone = person_boxes(CAMERAS, wrong[None])[0, 0]
            return [lone[None].astype(np.float32), np.zeros((0, 4), np.float32)]
        both = person_boxes(CAMERAS, TRUTH[None])[0].astype(np.float32)
        return [both[0][None], both[1][None]]

    tracker = Tracker(fps_hint=FPS, **RECOMMENDED)
    if not wired:
        update = tracker.update
        tracker.update = lambda t, xy, meta, **_: update(t, xy, meta)  # type: ignore[method-assign]
    pipeline = Pipeline(
        _NoRig(), detect, Hub(), num_cameras=2, runtime=runtime, tracker=tracker,
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
