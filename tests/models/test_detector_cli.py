"""`momloc detect` on real photographs, through the real CLI entry point."""

from __future__ import annotations

import json

import cv2
import numpy as np

from models.detector.preprocessing import box_iou
from models.detector.validation import background, person_frame
from service.cli import main


def test_detect_prints_boxes_and_writes_annotated_copies(tmp_path, capsys):
    frame, truth = person_frame("camera", 300, (0.3, 1.0))
    person = tmp_path / "snapshot.png"
    empty = tmp_path / "empty.png"
    cv2.imwrite(str(person), frame)
    cv2.imwrite(str(empty), background())
    assert main(["detect", str(person), str(empty)]) == 0
    out = capsys.readouterr().out
    assert f"{person}: 1 person (640x480)" in out and f"{empty}: 0 people" in out
    annotated = cv2.imread(str(tmp_path / "snapshot.detections.jpg"))
    assert annotated is not None and annotated.shape == frame.shape
    assert np.abs(annotated.astype(int) - frame).max() > 100  # the box was drawn
    assert (tmp_path / "empty.detections.jpg").is_file()

    out_dir = tmp_path / "out"
    assert main(["detect", "--json", "--out-dir", str(out_dir), str(person)]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["width"] == 640 and len(record["boxes"]) == 1
    assert box_iou(truth, np.array(record["boxes"]))[0, 0] > 0.6
    assert record["annotated"] == str(out_dir / "snapshot.detections.jpg")
    assert (out_dir / "snapshot.detections.jpg").is_file()


def test_detect_adds_the_shipped_keypoints(tmp_path, capsys):
    frame, truth = person_frame("astronaut", 300, (0.5, 0.9))
    person = tmp_path / "snapshot.png"
    cv2.imwrite(str(person), frame)
    assert main(["detect", "--json", "--no-write", str(person)]) == 0
    assert "keypoints" not in json.loads(capsys.readouterr().out)
    assert main(["detect", "--json", "--no-write", "--keypoints", str(person)]) == 0
    (points,) = json.loads(capsys.readouterr().out)["keypoints"]
    nose, left_shoulder = points[0], points[5]
    assert truth[0] < nose[0] < truth[2] and truth[1] < nose[1] < left_shoulder[1] < truth[3]


def test_detect_finds_a_1080p_snapshots_small_people_unless_told_to_squeeze(tmp_path, capsys):
    snapshot = tmp_path / "hd.png"
    tile, _ = person_frame("astronaut", 130, anchor=(0.5, 0.8))
    frame = np.full((1080, 1920, 3), tile[0, 0], np.uint8)
    frame[300:780, 640:1280] = tile
    cv2.imwrite(str(snapshot), frame)
    assert main(["detect", "--no-write", str(snapshot)]) == 0
    assert "1 person (1920x1080)" in capsys.readouterr().out
    assert main(["detect", "--no-write", "--max-shrink", "100", str(snapshot)]) == 0
    assert "0 people (1920x1080)" in capsys.readouterr().out
    assert main(["detect", "--detector", "ssdlite", "--max-shrink", "2", str(snapshot)]) == 2
    assert "bad option" in capsys.readouterr().err


def test_detect_errors_are_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.jpg"
    bad.write_bytes(b"no jpeg here")
    assert main(["detect", str(bad)]) == 2
    assert "not a readable image" in capsys.readouterr().err
    assert main(["detect", str(tmp_path / "absent.jpg")]) == 2
    assert "not found" in capsys.readouterr().err
    frame = tmp_path / "f.png"
    cv2.imwrite(str(frame), background())
    assert main(["detect", "--detector", "yolov8", str(frame)]) == 2
    assert "model_path" in capsys.readouterr().err
