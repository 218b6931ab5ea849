"""The --detections feed of `momloc track` (service/offline/track.py)."""

from __future__ import annotations

import dataclasses

import numpy as np

from models.data.dataset import MomDataset
from service.offline.track import detections_feed


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
        frames = [f for f in frame_set.frames if f is not None]
        assert [f.timestamp for f in frames] == [frame / 10.0] * 2
        assert all(f.image is None for f in frames)
        found = feed.detect(frame_set)
        if frame == 5:  # nobody seen: an empty frame set, so tracks age as they would live
            assert [len(d) for d in found] == [0, 0]
            continue
        lefts = [d.boxes[:, 0].tolist() for d in found]
        assert [sorted(x) for x in lefts] == [[100.0, 400.0]] * 2  # every box, nothing else
        same_order += lefts[0] == lefts[1]
    # row order (person 0 first) must not survive: each camera is shuffled on its own
    assert 10 < same_order < 49


def test_dataset_keypoints_ride_with_their_shuffled_boxes(tmp_path):
    """A keypoint model offline (``--detections`` of a dataset with keypoints): each box keeps
    its own person's keypoints through the per-camera shuffle."""
    data = two_people(30)
    keypoints = np.zeros((data.n, 2, 17, 3), np.float32)
    keypoints[..., 0] = data.boxes[:, :, None, 0] + 7.0  # x marks whose box it is
    keypoints[..., 2] = 1.0
    data = dataclasses.replace(data, keypoints=keypoints)
    feed = detections_feed(data.save(tmp_path / "k.npz"), fps=10.0, seed=2)
    assert feed.detect.keypoints
    checked = 0
    for _, frame_set in feed.frame_sets:
        for d in feed.detect(frame_set):
            assert d.keypoints is not None and d.keypoints.shape == (len(d), 17, 3)
            assert (d.keypoints[:, :, 0] == d.boxes[:, :1] + 7.0).all()
            checked += len(d)
    assert checked == 2 * 2 * 29


def test_a_dataset_without_keypoints_feeds_boxes_only(tmp_path):
    feed = detections_feed(two_people(8).save(tmp_path / "b.npz"), fps=10.0)
    assert not feed.detect.keypoints
    _, frame_set = next(iter(feed.frame_sets))
    assert all(d.keypoints is None for d in feed.detect(frame_set))


def test_a_replay_feeds_every_box_in_source_order_at_its_own_fps(tmp_path):
    """A detections replay (momloc import): boxes of nobody included, no shuffling (its rows
    carry no identity), frames without boxes as empty sets, the replay's fps by default."""
    from models.data.detections_replay import DetectionsReplay

    replay = DetectionsReplay(
        frame=np.array([3, 3, 3, 5]),
        camera=np.array([0, 0, 1, 1]),
        boxes=np.array([[10, 10, 20, 40], [50, 10, 60, 40], [1, 1, 2, 2], [5, 5, 9, 9]], float),
        scores=np.array([0.9, 0.3, 0.5, 0.7]),
        image_size=np.array([[640, 480], [320, 240]]),
        fps=4.0,
    )
    feed = detections_feed(replay.save(tmp_path / "r.npz"), fps=None)
    assert feed.total == 3 and feed.image_sizes == [(640, 480), (320, 240)]
    assert not feed.detect.keypoints
    seen = {}
    for frame, frame_set in feed.frame_sets:
        assert [f.timestamp for f in frame_set.frames if f is not None] == [frame / 4.0] * 2
        seen[frame] = [d.boxes[:, 0].tolist() for d in feed.detect(frame_set)]
    assert seen == {3: [[10.0, 50.0], [1.0]], 4: [[], []], 5: [[], [5.0]]}
    assert detections_feed(tmp_path / "r.npz", fps=10.0).total == 3
