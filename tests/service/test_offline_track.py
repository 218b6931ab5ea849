"""The --detections feed of `momloc track` (service/offline_track.py)."""

from __future__ import annotations

import numpy as np

from models.dataset import MomDataset
from service.offline_track import detections_feed


def two_people(frames: int) -> MomDataset:
    """Person 0 left and person 1 right in both cameras, every frame but frame 5 (empty)."""
    rows = [(f, p) for f in range(frames) if f != 5 for p in (0, 1)]
    boxes = np.array([[[100 + 300 * p, 100, 150 + 300 * p, 300]] * 2 for _, p in rows], np.float32)
    return MomDataset(
        world=np.array([[p, f * 0.01] for f, p in rows], np.float32),
        boxes=boxes,
        frame=np.array([f for f, _ in rows], np.int64),
        track=np.array([p for _, p in rows], np.int64),
        image_size=np.array([[640, 480]] * 2, np.int32),
    )


def test_dataset_boxes_come_frame_by_frame_shuffled_per_camera(tmp_path):
    path = two_people(60).save(tmp_path / "d.npz")
    feed = detections_feed(path, fps=10.0, seed=1)
    assert feed.total == 60 and feed.image_sizes == [(640, 480)] * 2
    same_order = 0
    for frame, frame_set in feed.frame_sets:
        assert [f.timestamp for f in frame_set.frames] == [frame / 10.0] * 2
        assert all(f.image is None for f in frame_set.frames)
        boxes = feed.detect(frame_set)
        if frame == 5:  # nobody seen: an empty frame set, so tracks age as they would live
            assert [len(b) for b in boxes] == [0, 0]
            continue
        lefts = [b[:, 0].tolist() for b in boxes]
        assert [sorted(x) for x in lefts] == [[100.0, 400.0]] * 2  # every box, nothing else
        same_order += lefts[0] == lefts[1]
    # row order (person 0 first) must not survive: each camera is shuffled on its own
    assert 10 < same_order < 49
