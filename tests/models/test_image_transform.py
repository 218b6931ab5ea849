"""A camera's image transform: boxes mapped back into the image the model learned, served."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from common.errors import MomlocError
from models.mom import image_transform
from models.mom.runtime import MomRuntime
from service.settings import DEMO_MODEL_DIR


def rolled(degrees: float, shift: tuple[float, float], about: tuple[float, float]) -> np.ndarray:
    """The image rolled by ``degrees`` about pixel ``about``, then shifted by ``shift``."""
    a = np.radians(degrees)
    h = np.eye(3)
    h[:2, :2] = [[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]
    to, back = np.eye(3), np.eye(3)
    to[:2, 2], back[:2, 2] = -np.asarray(about), np.asarray(about) + np.asarray(shift)
    return back @ h @ to


def seen_through(h: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """The boxes [N, 4] as the transformed camera shows them (the module's box model forward)."""
    centre = image_transform.apply(h, (boxes[:, :2] + boxes[:, 2:]) / 2)
    j = np.abs(image_transform.jacobian(h, (boxes[:, :2] + boxes[:, 2:]) / 2))
    w, height = boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1]
    size = np.c_[
        j[:, 0, 0] * w + image_transform.WIDTH_FROM_HEIGHT * j[:, 0, 1] * height,
        j[:, 1, 1] * height,
    ]
    return np.c_[centre - size / 2, centre + size / 2]


BOXES = np.array([[300.0, 150.0, 340.0, 260.0], [100.0, 200.0, 160.0, 380.0]])


def test_boxes_come_back_to_where_the_model_saw_them() -> None:
    assert np.allclose(image_transform.boxes_to_model(np.eye(3), BOXES), BOXES)
    h = rolled(3.0, (10.0, -4.0), (320.0, 240.0))
    back = image_transform.boxes_to_model(h, seen_through(h, BOXES))
    assert np.abs(back - BOXES).max() < 0.05
    keypoints = np.array([[[320.0, 200.0, 0.9], [330.0, 250.0, 0.2]]])
    moved = np.c_[image_transform.apply(h, keypoints[0, :, :2]), keypoints[0, :, 2:]][None]
    assert np.allclose(image_transform.keypoints_to_model(h, moved), keypoints)


@pytest.fixture
def repaired_dir(tmp_path: Path) -> tuple[Path, np.ndarray]:
    """A copy of the demo model whose camera 1 was rolled 3° and shifted 10 px since."""
    target = tmp_path / "model"
    shutil.copytree(DEMO_MODEL_DIR, target)
    meta = json.loads((target / "model.json").read_text())
    h = rolled(3.0, (10.0, 0.0), (320.0, 240.0))
    meta["image_transforms"] = [None, h.tolist()]
    (target / "model.json").write_text(json.dumps(meta))
    return target, h


def test_a_repaired_model_on_bumped_boxes_gives_the_former_positions(
    repaired_dir: tuple[Path, np.ndarray],
) -> None:
    target, h = repaired_dir
    former, repaired = MomRuntime.load(DEMO_MODEL_DIR), MomRuntime.load(target)
    boxes = np.array([[[250.0, 120.0, 290.0, 250.0], [300.0, 150.0, 340.0, 260.0]]] * 3)
    boxes[1, 0] = np.nan  # camera 1 alone
    boxes[2, 1] = np.nan  # camera 0 alone: untouched
    bumped = boxes.copy()
    bumped[:, 1] = seen_through(h, boxes[:, 1])
    expected = former.localize(boxes)
    assert np.abs(repaired.localize(bumped) - expected).max() < 0.01
    assert np.abs(former.localize(bumped)[:2] - expected[:2]).max() > 0.1  # the bump shows
    assert np.allclose(repaired.covariance(bumped), former.covariance(boxes), rtol=0.05)
    assert np.abs(repaired.encode(bumped) - former.encode(boxes)).max() < 0.02
    # the decoder answers in the camera's current image: the reprojection error is as before
    world = expected[:1]
    assert np.allclose(
        repaired.reproject(world)[:, 1], image_transform.apply(h, former.reproject(world)[:, 1])
    )
    assert np.allclose(
        repaired.reprojection_error(bumped[:1], world),
        former.reprojection_error(boxes[:1], world),
        atol=1.0,
    )


def test_a_transform_that_is_not_one_per_camera_or_not_invertible_is_refused(
    repaired_dir: tuple[Path, np.ndarray],
) -> None:
    target, _ = repaired_dir
    meta = json.loads((target / "model.json").read_text())
    for bad, why in (([None], "for 2 cameras"), ([None, [[0.0] * 3] * 3], "not invertible")):
        (target / "model.json").write_text(json.dumps({**meta, "image_transforms": bad}))
        with pytest.raises(MomlocError, match=why):
            MomRuntime.load(target)
