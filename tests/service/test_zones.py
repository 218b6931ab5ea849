"""Zone geometry and hysteresis (service.outputs.zones): pure logic, capture time only."""

from __future__ import annotations

import math

import numpy as np
import pytest

from service.outputs.zones import (
    Zone,
    ZoneTracker,
    point_in_polygon,
    segments_touch,
    validate_polygon,
)

SQUARE = [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)]
# concave "U": the notch (1..2 x 1..3) is outside although inside the bounding box
U_SHAPE = [(0, 0), (3, 0), (3, 3), (2, 3), (2, 1), (1, 1), (1, 3), (0, 3)]


def _ref_inside(x: float, y: float) -> bool:
    """Independent truth for U_SHAPE: union of three rectangles (edges inclusive)."""
    return (
        (0 <= x <= 3 and 0 <= y <= 1)
        or (0 <= x <= 1 and 0 <= y <= 3)
        or (2 <= x <= 3 and 0 <= y <= 3)
    )


# -- geometry ------------------------------------------------------------------------------------


def test_concave_polygon_matches_independent_truth_on_a_grid():
    poly = validate_polygon(U_SHAPE)
    wrong = []
    for x in np.linspace(-0.5, 3.5, 57):
        for y in np.linspace(-0.5, 3.5, 57):
            if point_in_polygon(float(x), float(y), poly) != _ref_inside(float(x), float(y)):
                wrong.append((round(float(x), 3), round(float(y), 3)))
    assert not wrong, wrong[:10]
    assert not point_in_polygon(1.5, 2.0, poly)  # inside the notch: outside the zone
    assert point_in_polygon(0.5, 2.5, poly) and point_in_polygon(2.5, 2.5, poly)


def test_points_on_edges_and_vertices_count_as_inside():
    poly = validate_polygon(SQUARE)
    for point in [(1.0, 0.0), (2.0, 1.0), (1.0, 2.0), (0.0, 1.0), (0, 0), (2, 2), (2, 0)]:
        assert point_in_polygon(*point, poly), point
    for point in [(1.0, -1e-6), (2.0 + 1e-6, 1.0), (-0.001, 2.0)]:
        assert not point_in_polygon(*point, poly), point
    # a ray through a vertex must not be counted twice (diamond, ray y=1 hits vertices)
    diamond = validate_polygon([(1, 0), (2, 1), (1, 2), (0, 1)])
    assert point_in_polygon(0.5, 1.0, diamond) and point_in_polygon(1.0, 1.0, diamond)
    assert not point_in_polygon(-0.5, 1.0, diamond) and not point_in_polygon(2.5, 1.0, diamond)
    # concave vertex edge of the U (inner corners)
    u = validate_polygon(U_SHAPE)
    assert (
        point_in_polygon(1.0, 1.0, u)
        and point_in_polygon(1.5, 1.0, u)
        and point_in_polygon(1, 2, u)
    )


def test_orientation_does_not_matter():
    poly = validate_polygon(list(reversed(U_SHAPE)))
    assert not point_in_polygon(1.5, 2.0, poly) and point_in_polygon(0.5, 0.5, poly)


@pytest.mark.parametrize(
    ("polygon", "message"),
    [
        ([(0, 0), (1, 0)], "at least 3"),
        ([(0, 0), (1, 0), (0, 0)], "at least 3"),  # closing vertex dropped -> 2 points
        ([(0, 0), (1, 0), (float("nan"), 1)], "not finite"),
        ([(0, 0), (1, 0), (math.inf, 1)], "not finite"),
        ([(0, 0), (1, 1), (2, 2)], "no area"),
        ([(0, 0), (2, 2), (2, 0), (0, 2)], "intersects itself"),  # bow tie
        ([(0, 0), (4, 0), (4, 4), (2, 4), (2, -1), (0, 4)], "intersects itself"),  # edge crosses
        ([(0, 0), (2, 0), (2, 2), (1, 0), (0, 2)], "intersects itself"),  # vertex on an edge
        ([(0, 0), (2, 0), (1, 0), (1, 1)], "intersects itself"),  # edges fold back
        ([(0, 0), (1, 0), (1, 0), (1, 1)], "are the same"),
        ([(0, 0, 0), (1, 0), (1, 1)], "must be [x, y]"),
    ],
)
def test_invalid_polygons_are_refused_with_the_reason(polygon, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        validate_polygon(polygon)


def test_valid_polygons_pass_including_closed_form_and_collinear_points():
    assert len(validate_polygon([*SQUARE, SQUARE[0]])) == 4
    assert len(validate_polygon(U_SHAPE)) == 8
    assert len(validate_polygon([(0, 0), (1, 0), (2, 0), (2, 2), (0, 2)])) == 5


def test_segments_touch():
    assert segments_touch((0, 0), (2, 2), (0, 2), (2, 0))
    assert segments_touch((0, 0), (2, 0), (1, 0), (1, 5))  # T junction
    assert segments_touch((0, 0), (2, 0), (1, 0), (3, 0))  # collinear overlap
    assert not segments_touch((0, 0), (2, 0), (3, 0), (4, 0))  # collinear, apart
    assert not segments_touch((0, 0), (1, 1), (0, 1), (0.4, 0.6001))


# -- hysteresis and events -----------------------------------------------------------------------


def _person(pid: int, x: float, y: float) -> dict:
    return {"id": pid, "x": x, "y": y}


def _run(tracker: ZoneTracker, frames):
    events = []
    for t, people in frames:
        events.extend(tracker.update(t, people))
    return events


def test_jitter_at_a_border_does_not_flap():
    zone = Zone.create("desk", SQUARE, hold_s=0.5)
    tracker = ZoneTracker([zone])
    rng = np.random.default_rng(0)
    frames = []
    t0 = 1000.0
    # 3 s walking in and settling inside, then 10 s jittering +-3 cm across the x=2 edge while
    # mostly inside: raw answers alternate every few frames, never 0.5 s outside in a row
    for i in range(90):
        frames.append((t0 + i / 30, [_person(1, 1.0 + i / 90, 1.0)]))
    for i in range(300):
        x = 2.0 + (0.03 if (i // 5) % 3 == 0 else -0.03) + rng.normal(0, 0.002)
        frames.append((t0 + 3 + i / 30, [_person(1, x, 1.0)]))
    events = _run(tracker, frames)
    assert [e["type"] for e in events] == ["enter"]
    assert tracker.states["desk"].count == 1


def test_hold_time_is_capture_time_and_reports_dwell():
    tracker = ZoneTracker([Zone.create("sofa", SQUARE, hold_s=0.5)])
    inside, outside = _person(7, 1, 1), _person(7, 5, 5)
    assert tracker.update(10.0, [inside]) == []
    assert tracker.update(10.49, [inside]) == []  # 0.49 s < hold
    (enter,) = tracker.update(10.5, [inside])
    assert enter["type"] == "enter" and enter["since"] == 10.0 and enter["t"] == 10.5
    assert enter["count"] == 1 and enter["ids"] == [7]
    assert tracker.update(20.0, [outside]) == []
    assert tracker.update(20.3, [inside]) == []  # back within hold: streak broken
    assert tracker.update(21.0, [outside]) == []
    (leave,) = tracker.update(21.6, [outside])
    assert leave["type"] == "leave" and leave["since"] == 21.0
    assert leave["dwell_s"] == pytest.approx(11.0)
    assert leave["count"] == 0 and leave["ids"] == []
    assert [enter["seq"], leave["seq"]] == [1, 2]


def test_frame_rate_does_not_change_the_events():
    """Same walk sampled at 30 and 7 fps: same events (within one sample of timing)."""

    def walk(fps: float):
        tracker = ZoneTracker([Zone.create("a", U_SHAPE, 0.5), Zone.create("b", SQUARE, 0.5)])
        frames = []
        for i in range(int(20 * fps)):
            t = i / fps
            frames.append((t, [_person(1, -1 + 0.25 * t, 0.5 + 0.1 * t)]))
        return [(e["type"], e["zone"]) for e in _run(tracker, frames)]

    assert walk(30) == walk(7) and len(walk(30)) >= 3


def test_a_vanished_person_leaves_after_the_hold_and_ids_are_independent():
    tracker = ZoneTracker([Zone.create("sofa", SQUARE, hold_s=0.5)])
    events = _run(
        tracker,
        [(t / 10, [_person(1, 1, 1), _person(2, 0.5, 0.5)]) for t in range(10)]
        + [(1.0 + t / 10, [_person(2, 0.5, 0.5)]) for t in range(10)],
    )
    assert [(e["type"], e["id"]) for e in events] == [("enter", 1), ("enter", 2), ("leave", 1)]
    assert tracker.states["sofa"].ids == [2]


def test_zero_hold_reports_at_once_and_time_never_runs_backwards():
    tracker = ZoneTracker([Zone.create("sofa", SQUARE, hold_s=0.0)])
    assert [e["type"] for e in tracker.update(5.0, [_person(1, 1, 1)])] == ["enter"]
    assert tracker.update(4.0, [_person(1, 1, 1)]) == []  # older snapshot: clamped, no event
    assert tracker.last_t == 5.0


def test_duplicate_zone_names_are_refused():
    with pytest.raises(ValueError, match="unique"):
        ZoneTracker([Zone.create("a", SQUARE), Zone.create("a", U_SHAPE)])
