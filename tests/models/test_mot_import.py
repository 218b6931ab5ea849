"""MOTChallenge detections + positions in (models.data.mot_import), replay out and back
(models.data.detections_replay): what lands in each file, and the one-line errors on bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from common.errors import MomlocError
from models.data.detections_replay import FORMAT, DetectionsReplay, is_replay
from models.data.mot_import import build_dataset, build_replay, read_mot, read_positions

CAM0 = """\
# frame, id, left, top, width, height, conf
1, 7, 10, 20, 30, 60, 0.9
1, -1, 300, 20, 30, 60, 0.4
2, 7, 12, 20, 30, 60, -1
"""
CAM1 = "1 8 100 50 40 80 0.8\n2 7 110 50 40 80 0.7 -1 -1 -1\n"
POSITIONS = "1,7,1.0,2.0\n1,8,3.0,1.0\n2,7,1.1,2.0\n2,9,5.0,5.0\n"


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text)
    return path


def test_mot_rows_become_xyxy_boxes_with_scores(tmp_path: Path) -> None:
    mot = read_mot(write(tmp_path, "c0.txt", CAM0))
    np.testing.assert_array_equal(mot.frame, [1, 1, 2])
    np.testing.assert_array_equal(mot.id, [7, -1, 7])
    np.testing.assert_allclose(mot.boxes[0], [10, 20, 40, 80])
    np.testing.assert_allclose(mot.scores, [0.9, 0.4, 1.0])  # -1: not given -> 1


def test_dataset_rows_are_positions_with_a_box_and_nan_elsewhere(tmp_path: Path) -> None:
    cams = [read_mot(write(tmp_path, "c0.txt", CAM0)), read_mot(write(tmp_path, "c1.txt", CAM1))]
    data = build_dataset(
        cams, read_positions(write(tmp_path, "p.txt", POSITIONS)), [(640, 480)] * 2
    )
    # (2, 9) has no box anywhere: no row; (1, 8) is seen by camera 1 only
    assert sorted(zip(data.frame.tolist(), data.track.tolist(), strict=True)) == [
        (1, 7),
        (1, 8),
        (2, 7),
    ]
    row = {(int(f), int(t)): i for i, (f, t) in enumerate(zip(data.frame, data.track, strict=True))}
    assert np.isnan(data.boxes[row[(1, 8)], 0]).all()
    np.testing.assert_allclose(data.boxes[row[(1, 8)], 1], [100, 50, 140, 130])
    np.testing.assert_allclose(data.boxes[row[(2, 7)]], [[12, 20, 42, 80], [110, 50, 150, 130]])
    np.testing.assert_allclose(data.world[row[(2, 7)]], [1.1, 2.0])


def test_replay_keeps_every_box_and_reads_back(tmp_path: Path) -> None:
    cams = [read_mot(write(tmp_path, "c0.txt", CAM0)), read_mot(write(tmp_path, "c1.txt", CAM1))]
    path = build_replay(cams, [(640, 480), (1280, 720)], fps=4.0).save(tmp_path / "r.npz")
    assert is_replay(path)
    replay = DetectionsReplay.load(path)
    assert replay.n == 5 and replay.fps == 4.0 and replay.num_cameras == 2
    boxes, scores = replay.at(1, 0)  # the box of nobody stays, in source order
    np.testing.assert_allclose(boxes[:, 0], [10, 300])
    np.testing.assert_allclose(scores, [0.9, 0.4])
    assert replay.at(3, 1)[0].shape == (0, 4)
    with np.load(path) as archive:
        assert str(archive["format"]) == FORMAT


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("1,7,10,20,30\n", "c.txt:1: field 'bb_height' missing"),
        ("# head\n1,7,10,abc,30,60\n", "c.txt:2: field 'bb_top': 'abc' is not a number"),
        ("1.5,7,10,20,30,60\n", "c.txt:1: field 'frame': 1.5 is not an integer"),
        ("1,7,10,20,-30,60\n", "c.txt:1: field 'bb_width': negative"),
        ("1,7,10,20,nan,60\n", "c.txt:1: field 'bb_width': nan is not finite"),
    ],
)
def test_bad_mot_lines_name_file_line_and_field(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(MomlocError, match=message):
        read_mot(write(tmp_path, "c.txt", text))


def test_bad_positions_and_ids(tmp_path: Path) -> None:
    with pytest.raises(MomlocError, match=r"p.txt:2: field 'id': person 7 already at frame 1"):
        read_positions(write(tmp_path, "p.txt", "1,7,1,2\n1,7,3,4\n"))
    with pytest.raises(MomlocError, match=r"p.txt:1: field 'y' missing"):
        read_positions(write(tmp_path, "p.txt", "1,7,1\n"))
    no_ids = read_mot(write(tmp_path, "c.txt", "1,-1,1,2,3,4\n"))
    positions = read_positions(write(tmp_path, "p.txt", POSITIONS))
    with pytest.raises(MomlocError, match="no row carries an id"):
        build_dataset([no_ids], positions, [(640, 480)])
    twice = read_mot(write(tmp_path, "c.txt", "1,7,1,2,3,4\n1,7,5,2,3,4\n"))
    with pytest.raises(MomlocError, match="id 7 has two boxes at frame 1"):
        build_dataset([twice], positions, [(640, 480)])
    with pytest.raises(MomlocError, match="no such file"):
        read_mot(tmp_path / "missing.txt")
