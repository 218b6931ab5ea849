"""The one chain: people outside the set-up area are dropped, or served flagged, and never reach
zones or MQTT unless asked; the live pipeline and the stream benchmark run the same object."""

from __future__ import annotations

import numpy as np
import pytest

from models.detector.base import Detections
from service.outputs.zone_monitor import ZoneMonitor
from service.outputs.zones import Zone
from service.pipeline.chain import Chain
from service.snapshot import Snapshot
from service.stages import Track
from service.tracking.tracker import RECOMMENDED, Tracker
from tests.people import person
from tests.service.mom_doubles import OracleRuntime, person_boxes, room_cameras

INSIDE_X = 4.0  # the fake set-up area: x below this


class AreaOracle(OracleRuntime):
    """The oracle localizer with a set-up area (x < 4 m), as ``MomRuntime.inside`` answers."""

    def inside(self, boxes: np.ndarray, world: np.ndarray) -> np.ndarray:
        return np.asarray(world)[:, 0] < INSIDE_X


def _frames(runtime: OracleRuntime, people: np.ndarray) -> list[Detections]:
    boxes = person_boxes(runtime.projections, people)
    return [
        Detections(boxes[:, k].astype(np.float32), np.ones(len(people), np.float32))
        for k in range(runtime.num_cameras)
    ]


def _run(chain: Chain, runtime: OracleRuntime, people: np.ndarray, seconds: float = 2.0):
    tracks: list[Track] = []
    for i in range(int(seconds * 10)):
        _, tracks = chain(i / 10, _frames(runtime, people), runtime, [True, True], i)
    return tracks


@pytest.fixture()
def runtime() -> AreaOracle:
    return AreaOracle(room_cameras(2))


PEOPLE = np.array([[2.0, 3.0], [5.2, 2.5]])  # one inside, one beyond x = 4


def test_people_outside_the_set_up_area_are_dropped_by_default(runtime):
    chain = Chain(Tracker(fps_hint=10, **RECOMMENDED))
    associations, _ = chain(0.0, _frames(runtime, PEOPLE), runtime, [True, True], 0)
    assert [a.inside for a in associations] == [True]
    # kept aside for the learning room only (service.learning.labels)
    assert [np.round(a.world, 1).tolist() for a in chain.outside] == [[5.2, 2.5]]
    assert not chain.outside[0].inside
    tracks = _run(chain, runtime, PEOPLE)
    assert len(tracks) == 1 and tracks[0].x == pytest.approx(2.0, abs=0.1)


def test_flagged_people_are_tracked_and_marked_but_zones_and_counts_ignore_them(runtime):
    from service.pipeline.live import served_person

    chain = Chain(Tracker(fps_hint=10, **RECOMMENDED), outside_area="flag")
    tracks = _run(chain, runtime, PEOPLE)
    people = sorted((served_person(tr) for tr in tracks), key=lambda p: p["x"])
    assert len(people) == 2
    assert "outside" not in people[0] and people[1]["outside"] is True
    snapshot = Snapshot.build(1, 0.0, people)
    assert [p["x"] for p in snapshot.inside_only().people] == [people[0]["x"]]
    monitor = ZoneMonitor([Zone.create("room", [(0, 0), (7, 0), (7, 7), (0, 7)], 0.0)])
    monitor.offer(snapshot)
    assert monitor.occupancy()[0]["count"] == 1


@pytest.mark.parametrize("policy, served", [("drop", [1]), ("flag", [1, 2])])
def test_a_track_served_beyond_the_area_is_outside_whatever_fed_it(runtime, policy, served):
    """A track fed inside the area whose filter is served beyond it (a lone view's correction,
    its velocity) is outside: dropped, or flagged so that zones, counts and falls skip it."""
    from service.pipeline.chain import gate_tracks_to_area
    from service.pipeline.live import served_person

    def track(pid: int, x: float) -> Track:
        return Track(id=pid, x=x, y=2.0, vx=0.0, vy=0.0, confidence=1.0, cameras=[0])

    kept = gate_tracks_to_area(
        [track(1, INSIDE_X - 0.1), track(2, INSIDE_X + 0.1)], runtime, policy
    )
    assert [tr.id for tr in kept] == served
    people = [served_person(tr) for tr in kept]
    assert [p.get("outside", False) for p in people] == [False, True][: len(served)]
    assert [p["id"] for p in Snapshot.build(1, 0.0, people).inside_only().people] == [1]


def test_a_model_without_an_area_keeps_everyone(runtime):
    plain = OracleRuntime(room_cameras(2))
    tracks = _run(Chain(Tracker(fps_hint=10, **RECOMMENDED)), plain, PEOPLE)
    assert len(tracks) == 2


def test_a_snapshot_without_outside_people_is_its_own_inside_view():
    snapshot = Snapshot.build(3, 1.0, [person(1)])
    assert snapshot.inside_only() is snapshot


def test_unknown_outside_policy_is_refused():
    with pytest.raises(ValueError, match="outside_area"):
        Chain(Tracker(), outside_area="hide")  # type: ignore[arg-type]


def test_a_tracked_person_is_one_association_despite_a_cut_box():
    """The chain hands the tracker's predictions to the association: a person whose third
    camera's box is off sideways in every frame (the floor maps disagree) is split in two by
    the boxes alone, and one association once their track is served."""
    from tests.service.test_association import FloorOracle

    runtime = FloorOracle(room_cameras(3))
    boxes = person_boxes(runtime.projections, np.array([[3.0, 3.0]]))
    boxes[0, 2, [0, 2]] += 60.0
    frames = [Detections(boxes[:, k].astype(np.float32), np.ones(1, np.float32)) for k in range(3)]
    delivered = [True] * 3
    for anchored in (False, True):
        chain = Chain(Tracker(fps_hint=10, **RECOMMENDED), track_anchors=anchored)
        counts = [len(chain(i / 10, frames, runtime, delivered, i)[0]) for i in range(20)]
        assert counts[:3] == [2, 2, 2]  # no track served yet: split
        assert set(counts[10:]) == ({1} if anchored else {2})
