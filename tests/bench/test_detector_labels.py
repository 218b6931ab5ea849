"""Integrity of the hand-checked person boxes the detector benchmark rests on."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest

from bench.detector.data import (
    PHOTO_LABELS,
    VTEST_LABELS,
    annotation_problems,
    file_sha256,
    load_labels,
)


@pytest.fixture(scope="module")
def vtest() -> dict:
    return load_labels(VTEST_LABELS)


def test_vtest_labels_are_consistent(vtest: dict) -> None:
    assert annotation_problems(vtest) == []
    assert "checked and corrected by eye" in vtest["labels"]
    assert len(vtest["video"]["sha256"]) == 64
    assert vtest["counts"]["frames"] >= 25 and vtest["counts"]["boxes"] >= 200
    # Spread over the whole video, not one stretch of it.
    indices = vtest["frame_indices"]
    assert indices[0] < 60 and indices[-1] > 700


@pytest.mark.parametrize(
    "damage, expected",
    [
        (lambda d: d["frames"]["300"][0]["box"].__setitem__(2, 800), "not inside 768x576"),
        (lambda d: d["frames"]["300"].pop(), "counts.boxes"),
        (lambda d: d["frames"]["300"][0].__setitem__("origin", "guessed"), "origin"),
        (lambda d: d["frames"]["300"][0].__setitem__("occluded", 1), "occluded is not"),
        (lambda d: d["frame_indices"].append(999), "frame_indices"),
        (lambda d: d["frames"]["300"][0]["box"].__setitem__(0, 0), "touches border"),
    ],
)
def test_checker_finds_damage(vtest: dict, damage, expected: str) -> None:
    broken = copy.deepcopy(vtest)
    damage(broken)
    problems = annotation_problems(broken)
    assert any(expected in p for p in problems), problems


def test_vtest_video_matches_the_labels_when_installed(vtest: dict) -> None:
    path = Path(vtest["video"]["path"])
    if not path.is_file():
        pytest.skip(f"{path} not installed (apt-get install opencv-doc)")
    assert file_sha256(path) == vtest["video"]["sha256"]


def test_photo_labels_are_inside_their_photographs() -> None:
    doc = load_labels(PHOTO_LABELS)
    assert doc["counts"]["boxes"] == sum(len(rows) for rows in doc["photos"].values())
    for rows in doc["photos"].values():
        for row in rows:
            x0, y0, x1, y1 = row["box"]
            assert 0 <= x0 < x1 <= 512 and 0 <= y0 < y1 <= 512
            assert row["truncated"]  # both photographs cut people at the bottom
    assert not set(doc["no_people"]) & set(doc["photos"])
