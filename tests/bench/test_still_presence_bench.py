"""The seated hour's id score (``bench.serving.still_presence.id_changes``)."""

from __future__ import annotations

from bench.serving.still_presence import id_changes


def test_a_false_track_nearer_for_a_frame_is_no_id_change() -> None:
    serving = [1] * 20 + [7] + [1] * 20 + [None] * 10 + [1] * 5
    assert id_changes(serving, frame_s=0.2) == 0


def test_a_new_id_that_keeps_serving_the_sitter_is_one_change_each_time() -> None:
    serving = [1] * 20 + [None] * 15 + [9] * 20 + [1] * 6
    assert id_changes(serving, frame_s=0.2) == 2
    passing = [1] * 20 + [9] * 4 + [1] * 20  # id 9 nearer for 0.8 s in all
    assert id_changes(passing, frame_s=0.2) == 0
    assert id_changes(passing, frame_s=0.2, min_s=0.5) == 2
