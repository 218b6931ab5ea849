"""Dataset v1: round trip, and one test per rejection the format promises."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from models.data.dataset import DatasetError, MomDataset, validate_arrays


def _arrays(n: int = 5, k: int = 2, keypoints: bool = True) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    xy = rng.uniform(100, 300, size=(n, k, 2)).astype(np.float32)
    boxes = np.concatenate([xy, xy + 50], axis=-1)
    boxes[0, 1] = np.nan
    out = {
        "world": rng.uniform(0, 5, size=(n, 2)).astype(np.float32),
        "boxes": boxes,
        "frame": np.arange(n, dtype=np.int64),
        "track": np.zeros(n, dtype=np.int64),
        "image_size": np.array([[640, 480]] * k, dtype=np.int32),
    }
    if keypoints:
        out["keypoints"] = rng.uniform(0, 400, size=(n, k, 17, 3)).astype(np.float32)
    return out


def test_round_trip_keeps_arrays_and_nan(tmp_path: Path) -> None:
    data = MomDataset(**_arrays())
    path = data.save(tmp_path / "d.npz")
    loaded = MomDataset.load(path)
    for key, value in data.arrays().items():
        np.testing.assert_array_equal(loaded.arrays()[key], value)
        assert loaded.arrays()[key].dtype == value.dtype
    assert loaded.visible().tolist()[0] == [True, False]
    assert "5 instances" in loaded.summary() and "cam1 80%" in loaded.summary()


def test_wider_dtypes_are_narrowed() -> None:
    arrays = _arrays(keypoints=False)
    arrays["boxes"] = arrays["boxes"].astype(np.float64)
    arrays["frame"] = arrays["frame"].astype(np.int32)
    out = validate_arrays(arrays)
    assert out["boxes"].dtype == np.float32 and out["frame"].dtype == np.int64


def _corrupt(key: str, value: object) -> dict[str, object]:
    arrays: dict[str, object] = dict(_arrays())
    if value is None:
        del arrays[key]
    else:
        arrays[key] = value
    return arrays


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("world", None, "key 'world': missing"),
        ("boxes", None, "key 'boxes': missing"),
        ("world", np.zeros((5, 4), np.float32), "key 'world': shape"),
        ("boxes", np.zeros((5, 2, 3), np.float32), "key 'boxes': shape"),
        ("boxes", np.zeros((5, 10, 4), np.float32), "10 cameras"),
        ("boxes", np.zeros((5, 2, 4), np.int32), "key 'boxes': dtype"),
        ("frame", np.arange(5, dtype=np.float32), "key 'frame': dtype"),
        ("track", np.zeros(4, np.int64), "key 'track': 4 rows"),
        ("image_size", np.array([[640, 480]], np.int32), "key 'image_size': 1 cameras"),
        ("image_size", np.array([[640, 0], [640, 480]], np.int32), "must be positive"),
        ("keypoints", np.zeros((5, 3, 17, 3), np.float32), "key 'keypoints': leading shape"),
        ("extra", np.zeros(3), "key 'extra': not part"),
    ],
)
def test_rejections_name_the_key(key: str, value: object, message: str) -> None:
    with pytest.raises(DatasetError, match=message.replace("[", r"\[")):
        validate_arrays(_corrupt(key, value))


def test_rejects_flipped_box() -> None:
    arrays = _arrays()
    arrays["boxes"][2, 0] = [300, 100, 200, 150]
    with pytest.raises(DatasetError, match="row 2 camera 0 has xmax < xmin"):
        validate_arrays(arrays)


def test_rejects_infinite_values() -> None:
    arrays = _arrays()
    arrays["boxes"][1, 1, 2] = np.inf
    with pytest.raises(DatasetError, match="key 'boxes': contains infinite"):
        validate_arrays(arrays)
    arrays = _arrays()
    arrays["world"][0, 0] = np.nan
    with pytest.raises(DatasetError, match="key 'world': contains NaN"):
        validate_arrays(arrays)


def test_rejects_partly_missing_box() -> None:
    arrays = _arrays()
    arrays["boxes"][3, 0, 1] = np.nan
    with pytest.raises(DatasetError, match="partly NaN"):
        validate_arrays(arrays)


def test_load_names_the_file_for_garbage(tmp_path: Path) -> None:
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(DatasetError, match=r"bad\.npz: not a readable \.npz"):
        MomDataset.load(bad)
    with pytest.raises(DatasetError, match="no such file"):
        MomDataset.load(tmp_path / "absent.npz")


def test_save_is_atomic_and_leaves_no_temp_files(tmp_path: Path) -> None:
    MomDataset(**_arrays()).save(tmp_path / "d.npz")
    assert [p.name for p in tmp_path.iterdir()] == ["d.npz"]


def test_cli_prints_one_line_for_malformed_file(tmp_path: Path) -> None:
    arrays = _arrays()
    del arrays["track"]
    path = tmp_path / "m.npz"
    np.savez(path, **arrays)  # type: ignore[arg-type]  # numpy's stub: a keyword named allow_pickle
    result = subprocess.run(
        [sys.executable, "-m", "service.cli", "eval", "no-such-model", str(path)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
