"""Serving runtime: localizes, reprojects, handles missing views and refuses wrong inputs."""

import json
import sys

import numpy as np
import pytest

from common.errors import MomlocError
from models.mom.runtime import MomRuntime
from tests.models.mom_scene import make_dataset, trained_model


def test_localize_and_reprojection_on_fresh_data():
    out, _, _ = trained_model()
    runtime = MomRuntime.load(out)
    assert runtime.num_cameras == 2 and runtime.observation == "bbox"
    assert runtime.image_sizes.tolist() == [[640, 480], [640, 480]]
    data, _ = make_dataset(400, cameras=2, seed=21)
    world = runtime.localize(data.boxes)
    error = np.linalg.norm(world - data.world, axis=1)
    assert np.median(error) < 0.25
    # the decoder explains the observations: small error at the truth, large at a wrong place
    good = runtime.reprojection_error(data.boxes, data.world)
    bad = runtime.reprojection_error(data.boxes, data.world + 1.5)
    assert np.isnan(good[~data.visible()]).all()
    assert np.nanmedian(good) < 15 < np.nanmedian(bad)


def test_results_do_not_depend_on_batch_composition():
    out, _, _ = trained_model()
    runtime = MomRuntime.load(out)
    data, _ = make_dataset(64, cameras=2, seed=22)
    full = runtime.localize(data.boxes)
    one = np.stack([runtime.localize(data.boxes[i : i + 1])[0] for i in range(5)])
    np.testing.assert_allclose(full[:5], one, atol=1e-6)
    np.testing.assert_allclose(runtime.localize(data.boxes[::-1])[::-1], full, atol=1e-6)


def test_missing_views():
    out, _, _ = trained_model()
    runtime = MomRuntime.load(out)
    data, _ = make_dataset(300, cameras=2, seed=23)
    boxes = data.boxes.copy()
    boxes[:, 1] = np.nan
    world = runtime.localize(boxes)
    seen = np.isfinite(boxes[:, 0]).all(axis=1)
    assert np.isfinite(world[seen]).all()
    assert np.isnan(runtime.localize(np.full((1, 2, 4), np.nan))).all()


def test_wrong_camera_count_and_bad_directories(tmp_path):
    out, _, _ = trained_model()
    runtime = MomRuntime.load(out)
    with pytest.raises(MomlocError, match=r"3 cameras.*trained for 2"):
        runtime.localize(np.zeros((1, 3, 4), np.float32))
    # the same words for a missing path, a file and a directory without model.json: the reload
    # endpoint must not tell a caller which paths exist
    (tmp_path / "file.txt").write_text("x")
    for path in (tmp_path / "nothing", tmp_path / "file.txt", tmp_path):
        with pytest.raises(MomlocError, match=r"not a model directory \(no model\.json\)$"):
            MomRuntime.load(path)
    (tmp_path / "model.json").write_text(json.dumps({"format": "other"}))
    with pytest.raises(MomlocError, match="not a MoM model"):
        MomRuntime.load(tmp_path)


def test_keypoint_model_round_trip():
    out, data, _ = trained_model("keypoints")
    runtime = MomRuntime.load(out)
    assert runtime.observation == "keypoints"
    assert data.keypoints is not None
    world = runtime.localize(data.boxes[:100], data.keypoints[:100])
    assert np.median(np.linalg.norm(world - data.world[:100], axis=1)) < 0.3
    with pytest.raises(MomlocError, match="keypoints"):
        runtime.localize(data.boxes[:2])


def test_runtime_does_not_import_torch():
    import subprocess

    code = "import sys, models.mom.runtime; sys.exit('torch' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


def test_overlong_model_dir_is_one_short_error(tmp_path):
    """A path the OS refuses (> 255 bytes per name) is a MomlocError, and the echo is capped."""
    for path in ("x" * 300, str(tmp_path / ("y" * 100_000))):
        with pytest.raises(MomlocError, match="not a model directory") as info:
            MomRuntime.load(path)
        assert len(str(info.value)) < 250


def _model_copy(tmp_path, **changes):
    from service.settings import DEMO_MODEL_DIR

    meta = json.loads((DEMO_MODEL_DIR / "model.json").read_text())
    meta.update(changes)
    (tmp_path / "encoder.onnx").write_bytes((DEMO_MODEL_DIR / "encoder.onnx").read_bytes())
    (tmp_path / "model.json").write_text(json.dumps(meta))
    return tmp_path


@pytest.mark.parametrize(
    ("changes", "key"),
    [
        ({"encoder": "x"}, "encoder"),
        ({"num_cameras": "2"}, "num_cameras"),
        ({"image_sizes": [[640, 480]]}, "image_sizes"),
        ({"image_sizes": [[640, 480], [640, -1]]}, "image_sizes.1.1"),
        ({"sampler": []}, "sampler"),
        ({"sampler": {"num_points": "many"}}, "sampler.num_points"),
        ({"draws": {"unit": 1}}, "draws.unit"),
        ({"decoder": {"matrices": [[1, 2]]}}, "decoder.matrices"),
        ({"floor_prior": {"policy": 3}}, "floor_prior.policy"),
        ({"encoder": {"file": "../../etc/passwd"}}, "encoder.file"),
        ({"world_bounds": {"xmin": 0, "xmax": 1, "ymin": 0}}, "world_bounds.ymax"),
        ({"world_bounds": {"xmin": 2.0, "xmax": 1.0, "ymin": 0.0, "ymax": 1.0}}, "world_bounds"),
    ],
)
def test_model_json_with_wrong_types_names_the_key(tmp_path, changes, key):
    model = _model_copy(tmp_path, **changes)
    with pytest.raises(MomlocError) as info:
        MomRuntime.load(model)
    message = str(info.value)
    assert f"model.json: {key}" in message and "\n" not in message, message


def test_covariance_follows_the_floor_prior_and_the_view_count():
    out, _, _ = trained_model()
    runtime = MomRuntime.load(out)
    data, _ = make_dataset(200, cameras=2, seed=24)
    both = data.visible().all(axis=1)
    boxes = data.boxes[both][:50]
    cov = runtime.covariance(boxes)
    if runtime.floor_prior is None:  # no prior: the tracker's default applies
        assert np.isnan(cov).all()
        return
    assert cov.shape == (len(boxes), 2, 2) and np.isfinite(cov).all()
    np.testing.assert_allclose(cov, cov.transpose(0, 2, 1), atol=1e-12)
    one = boxes.copy()
    one[:, 1] = np.nan
    single = runtime.covariance(one)
    assert (np.trace(single, axis1=1, axis2=2) > np.trace(cov, axis1=1, axis2=2)).all()
    assert np.isnan(runtime.covariance(np.full((1, 2, 4), np.nan))).all()


def test_world_bounds_are_the_training_positions_extent_and_absent_in_older_models(tmp_path):
    from service.daemon import floor_extent
    from service.settings import DEMO_MODEL_DIR, Settings

    out, data, _ = trained_model()
    meta = json.loads((out / "model.json").read_text())
    xy = data.world[:, :2]
    expected = {
        "xmin": float(xy[:, 0].min()),
        "xmax": float(xy[:, 0].max()),
        "ymin": float(xy[:, 1].min()),
        "ymax": float(xy[:, 1].max()),
    }
    assert meta["world_bounds"] == pytest.approx(expected)
    runtime = MomRuntime.load(out)
    assert runtime.world_bounds is not None
    (xmin, ymin), (xmax, ymax) = runtime.world_bounds
    assert [xmin, ymin, xmax, ymax] == pytest.approx(
        [expected["xmin"], expected["ymin"], expected["xmax"], expected["ymax"]]
    )
    # the daemon's map extent: settings first, else the model's training area
    settings = Settings(cameras=[{"type": "v4l2", "device": "0"}] * 2)
    assert floor_extent(settings, runtime, None) == pytest.approx(expected)
    # a model written before world_bounds was stored loads, and the map falls back as before
    older_dir = tmp_path / "older"
    older_dir.mkdir()
    meta = json.loads((DEMO_MODEL_DIR / "model.json").read_text())
    meta.pop("world_bounds", None)
    meta.pop("setup_area", None)
    (older_dir / "model.json").write_text(json.dumps(meta))
    (older_dir / "encoder.onnx").write_bytes((DEMO_MODEL_DIR / "encoder.onnx").read_bytes())
    older = MomRuntime.load(older_dir)
    assert older.world_bounds is None and floor_extent(settings, older, None) is None
