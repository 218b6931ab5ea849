"""The self-label rules: what is kept from a frame set and why the rest is rejected."""

from __future__ import annotations

import numpy as np

from service.learning.labels import LabelRules, select_labels
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
