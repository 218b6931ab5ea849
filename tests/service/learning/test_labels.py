"""The self-label rules: what is kept from a frame set and why the rest is rejected."""

from __future__ import annotations

import numpy as np

from service.learning.labels import BEYOND_TRACK, BeyondMemory, LabelRules, select_labels
from tests.service.learning.frames import Person, frame_result

A = [100.0, 100.0, 160.0, 300.0]
B = [400.0, 120.0, 450.0, 280.0]
C = [300.0, 100.0, 350.0, 260.0]
D = [200.0, 90.0, 260.0, 300.0]
RULES = LabelRules()


def test_a_well_seen_person_is_kept_with_every_camera_box() -> None:
    result = select_labels(frame_result([Person(2.0, 3.0, [A, B])]), RULES, set(), {})
    assert result.labels is not None and result.labels.n == 1
    labels = result.labels
    np.testing.assert_allclose(labels.world[0], [2.0, 3.0])
    np.testing.assert_allclose(labels.boxes[0], [A, B])
    assert labels.keypoints.shape == (1, 2, 17, 3)
    assert labels.t[0] == 100.0 and labels.track[0] == 1
    assert np.isclose(labels.std_m()[0], 0.05)
    assert not result.rejected


def test_each_doubtful_moment_is_rejected_with_its_reason() -> None:
    cases = {
        "views": Person(2, 3, [A, None]),
        "covariance": Person(2, 3, [A, B], std_m=0.4),
        "cost": Person(2, 3, [A, B], cost=80.0),
        "coasting": Person(2, 3, [A, B], coasting=True),
    }
    for reason, person in cases.items():
        result = select_labels(frame_result([person]), RULES, set(), {})
        assert result.labels is None, reason
        assert result.rejected == {reason: 1}


def test_a_raised_camera_moved_check_rejects_its_views() -> None:
    result = select_labels(frame_result([Person(2, 3, [A, B])]), RULES, {1}, {})
    assert result.labels is None and result.rejected == {"camera_moved": 1}


def test_two_people_close_together_are_both_rejected() -> None:
    people = [Person(2, 3, [A, B], track=1), Person(2.5, 3.2, [C, D], track=2)]
    result = select_labels(frame_result(people), RULES, set(), {})
    assert result.labels is None and result.rejected == {"crowded": 2}


def test_overlapping_boxes_reject_a_person_even_far_apart_on_the_floor() -> None:
    overlapping = [150.0, 120.0, 210.0, 310.0]  # touches A in camera 0
    people = [Person(2, 3, [A, B], track=1), Person(6, 7, [overlapping, C], track=2)]
    result = select_labels(frame_result(people), RULES, set(), {})
    assert result.labels is None and result.rejected == {"overlap": 2}


def test_one_label_per_person_per_interval() -> None:
    last: dict[int, float] = {}
    kept = []
    for t in (100.0, 100.2, 100.4, 100.6):
        result = select_labels(frame_result([Person(2, 3, [A, B])], t=t), RULES, set(), last)
        kept.append(result.labels is not None)
    assert kept == [True, False, False, True]


def test_a_person_beyond_the_set_up_area_is_learned_once_two_frame_sets_agree() -> None:
    memory = BeyondMemory()
    kept, why = [], []
    for t, x in ((100.0, 6.0), (100.2, 6.1), (100.4, 6.2), (100.8, 7.5), (101.0, 7.6)):
        frame = frame_result([], t=t, beyond=[Person(x, 3, [A, B], track=0)])
        result = select_labels(frame, RULES, set(), {}, memory)
        kept.append(None if result.labels is None else result.labels.track.tolist())
        why.append(dict(result.rejected))
    # confirmed by the next frame set at about the same place; one label per place and interval
    assert kept == [None, [BEYOND_TRACK], None, None, [BEYOND_TRACK]]
    assert why == [{"beyond_unconfirmed": 1}, {}, {"beyond_rate": 1}, {"beyond_unconfirmed": 1}, {}]


def test_beyond_the_area_one_view_or_a_doubtful_moment_gives_no_label() -> None:
    cases = {
        "beyond_views": Person(6, 3, [A, None]),
        "beyond_covariance": Person(6, 3, [A, B], std_m=0.4),
        "beyond_cost": Person(6, 3, [A, B], cost=80.0),
    }
    for reason, person in cases.items():
        memory = BeyondMemory()
        for t in (100.0, 100.2):
            result = select_labels(frame_result([], t=t, beyond=[person]), RULES, set(), {}, memory)
        assert result.labels is None and result.rejected == {reason: 1}, reason


def test_people_beyond_the_area_are_ignored_without_a_memory_and_crowd_the_tracked() -> None:
    frame = frame_result([Person(2, 3, [A, B])], beyond=[Person(2.5, 3, [C, D], track=0)])
    assert select_labels(frame, RULES, set(), {}).rejected == {}
    assert select_labels(frame, RULES, set(), {}).labels is not None
    crowded = select_labels(frame, RULES, set(), {}, BeyondMemory())
    assert crowded.labels is None and crowded.rejected == {"crowded": 1, "beyond_crowded": 1}
