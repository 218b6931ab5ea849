"""The self-label listener: labels per room, and a slow worker never holds the pipeline up."""

from __future__ import annotations

import threading
from pathlib import Path

from service.learning.labels import LabelRules
from service.learning.listener import QUEUE_SIZE, SelfLabeler
from tests.service.learning.frames import FakeModel, Person, frame_result

A = [100.0, 100.0, 160.0, 300.0]
B = [400.0, 120.0, 450.0, 280.0]


def test_labels_go_to_the_serving_models_room(tmp_path: Path) -> None:
    labeler = SelfLabeler(tmp_path, rules=LabelRules(min_interval_s=0.0), threaded=False)
    first, second = FakeModel(), FakeModel(meta={"num_cameras": 2, "id": 2})
    for i in range(3):
        labeler(frame_result([Person(2, 3, [A, B])], t=float(i), model=first))
    room = labeler.room
    assert labeler.stats()["self_labels"] == 3
    labeler(frame_result([Person(2, 3, [A, B])], t=5.0, model=second))
    assert labeler.room != room and labeler.stats()["self_labels"] == 1
    labeler(frame_result([Person(2, 3, [A, None])], t=6.0, model=second))
    assert labeler.stats()["rejected"] == {"views": 1}
    labeler.close()
    assert len(list((tmp_path / "learning" / str(room)).glob("labels-*.npz"))) == 1


def test_a_busy_worker_drops_frame_sets_instead_of_queueing_them(tmp_path: Path) -> None:
    release = threading.Event()
    entered = threading.Event()

    def moved() -> set[int]:  # the worker's first step waits here
        entered.set()
        release.wait(10)
        return set()

    labeler = SelfLabeler(tmp_path, moved=moved)
    model = FakeModel()
    labeler(frame_result([Person(2, 3, [A, B])], t=0.0, model=model))
    assert entered.wait(10)
    for i in range(QUEUE_SIZE + 10):  # returns at once although nothing is processed
        labeler(frame_result([Person(2, 3, [A, B])], t=1.0 + i, model=model))
    assert labeler.dropped == 10
    release.set()
    labeler.close()
    assert labeler.stats()["frames_seen"] == QUEUE_SIZE + 1
