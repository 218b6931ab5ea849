"""The still-person rule: a false box shown while the person is missed is not recorded."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from models.dataset import MomDataset
from service.setup.collector import (
    DatasetAppender,
    FeedFrame,
    Step,
    collect,
    frame_row,
    plan_steps,
)
from service.setup.keep_rule import keep_mask
from service.setup.marks import FloorMark
from service.setup.quality import MarkQuality

FRAMES = 200  # 20 s at 10 Hz on one mark
MISSED = range(40, 200, 10)  # camera 1 misses the person here and shows a false box instead


def person(rng: np.random.Generator, scale: float, n: int) -> np.ndarray:
    """A swaying person's boxes [n, 4] at (300, 400) foot, 200 px tall at ``scale`` 1, with a
    measured detector's edge noise (bottom and top 0.10 and 0.035 box heights, sides 0.05)."""
    t = np.arange(n) / 10
    height = 200.0 * (1 + 0.05 * rng.standard_normal(n))
    u = 300 + 12 * np.sin(2 * np.pi * t / 4) + 0.05 * 200 * rng.standard_normal(n)
    bottom = 400 + 0.10 * 200 * rng.standard_normal(n)
    top = bottom - height + 0.035 * 200 * rng.standard_normal(n)
    width = 0.4 * height * (1 + 0.3 * np.sin(2 * np.pi * t / 7))  # turning in place
    return scale * np.stack([u - width / 2, top, u + width / 2, bottom], axis=1)


def false_box(scale: float) -> np.ndarray:
    """A coat on a chair: a person-sized box where nobody stands (a detector's lasting error)."""
    return scale * np.array([[480.0, 260.0, 540.0, 410.0]])


class MissFeed:
    """One mark; camera 0 sees the person always, camera 1 except at ``MISSED`` frames, where
    its only box is a false one. Boxes at any image scale."""

    def __init__(self, scale: float = 1.0) -> None:
        self.scale = scale
        self.image_sizes = (np.array([[640, 480], [640, 480]]) * scale).astype(np.int32)
        rng = np.random.default_rng(4)
        self.boxes = [person(rng, scale, FRAMES), person(rng, scale, FRAMES)]

    def prepare(self, steps: list[Step]) -> None:
        pass

    def frames(self, step: Step) -> Iterator[FeedFrame]:
        n = round(step.seconds * 10)
        for i in range(n):
            if step.kind != "record":
                yield FeedFrame(i / 10, [self.boxes[0][:1], self.boxes[1][:1]])
                continue
            second = false_box(self.scale) if i in MISSED else self.boxes[1][i : i + 1]
            yield FeedFrame(i / 10, [self.boxes[0][i : i + 1], second])


def record(tmp_path: Path, feed: MissFeed) -> tuple[MomDataset, dict]:
    mark = FloorMark("B2", 5, 5)
    quality = MarkQuality([mark], 2)
    writer = quality.counting(DatasetAppender(tmp_path / "room.npz", feed.image_sizes))
    steps = plan_steps([mark], FRAMES / 10, start=(5, 5), move_s=0.5, countdown_s=0.2)
    collect(feed, steps, writer, on_progress=lambda p: quality.frame(p.step, p.cameras_seeing))
    quality.finish()
    (report,) = quality.report()
    return MomDataset.load(tmp_path / "room.npz"), report


def test_the_old_frame_rule_records_the_false_box(tmp_path: Path) -> None:
    """The premise: per frame, a lone false box looks like the person."""
    feed = MissFeed()
    frame = FeedFrame(0, [feed.boxes[0][:1], false_box(1.0)])
    row = frame_row(frame, False)
    assert row is not None
    np.testing.assert_allclose(row[0][1], false_box(1.0)[0])


@pytest.mark.parametrize("scale", [0.25, 1.0, 6.0])  # 160x120 to 3840x2880: sizes do not matter
def test_false_boxes_are_dropped_and_counted(tmp_path: Path, scale: float) -> None:
    data, report = record(tmp_path, MissFeed(scale))
    assert data.n == FRAMES  # camera 0 saw the person in every frame: every row is kept
    fake = false_box(scale)[0]
    recorded_fake = np.isclose(data.boxes[:, 1], fake).all(axis=1)
    assert not recorded_fake.any()
    unseen_1 = np.isnan(data.boxes[:, 1]).all(axis=1)
    assert unseen_1.sum() >= len(MISSED)
    # the noisy, swaying person is kept (a few of 400 boxes may be beyond 4 robust sigmas)
    assert report["dropped_per_camera"][1] >= len(MISSED)
    assert sum(report["dropped_per_camera"]) <= len(MISSED) + 6
    assert report["per_camera"][0] >= FRAMES - 3


def test_a_camera_with_only_the_false_box_loses_the_frame_when_all_are_required() -> None:
    rng = np.random.default_rng(1)
    boxes = np.stack([person(rng, 1, 50), person(rng, 1, 50)], axis=1)
    boxes[10, 1] = false_box(1.0)[0]
    boxes[20, 0] = np.nan
    keep = keep_mask(boxes)
    assert not keep[10, 1] and not keep[20, 0]
    assert keep[np.r_[0:10, 11:50], 1].mean() > 0.95


def test_a_still_noise_free_person_is_never_dropped() -> None:
    boxes = np.tile([[[100.0, 50.0, 160.0, 250.0]]], (30, 1, 1))
    boxes[:, 0, ::2] += np.linspace(0, 3, 30)[:, None]  # a pixel or three of sway
    assert keep_mask(boxes).all()
