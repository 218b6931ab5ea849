"""`momloc eval` driven as a user runs it: a real trained model directory, a real .npz file."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from models.data.dataset import MomDataset
from models.data.metrics import METRIC_KEYS
from models.mom.evaluate import evaluate
from tests.models.test_evaluate import _dataset

ROOT = Path(__file__).resolve().parents[2]


def _momloc(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "service.cli", *args],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
    )


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    from models.mom.training.train import train_model

    folder = tmp_path_factory.mktemp("eval")
    train_model(_dataset(400), folder / "model", epochs=3, seed=0, progress=False)
    data = folder / "test.npz"
    _dataset(120).save(data)
    return folder / "model", data


def test_json_is_one_object_with_the_contract_keys(trained: tuple[Path, Path]) -> None:
    model, data = trained
    done = _momloc("eval", str(model), str(data), "--json")
    assert done.returncode == 0, done.stderr
    payload = json.loads(done.stdout)  # the whole stdout is exactly one JSON object
    assert tuple(payload) == METRIC_KEYS
    assert payload["n"] == 119  # row 5 is seen by no camera: counted out, noted on stderr
    assert "1 row(s) seen by no camera" in done.stderr
    # the CLI reports what the evaluation core computes on the same files
    from models.mom.runtime import MomRuntime

    expected = evaluate(MomRuntime.load(model), MomDataset.load(data)).metrics
    for key in METRIC_KEYS:
        assert payload[key] == pytest.approx(expected[key], rel=1e-6, abs=1e-9)
    assert 0 <= payload["acc@0.2"] <= payload["acc@0.5"] <= 100


def test_table_output(trained: tuple[Path, Path]) -> None:
    model, data = trained
    done = _momloc("eval", str(model), str(data))
    assert done.returncode == 0, done.stderr
    assert "Acc@0.3 m" in done.stdout and "ATE" in done.stdout and "2 cameras" in done.stdout


def test_other_camera_count_is_refused_in_one_line(trained: tuple[Path, Path], tmp_path) -> None:
    model, _ = trained
    three = _dataset(30)
    arrays = three.arrays()
    arrays["boxes"] = np.concatenate([arrays["boxes"], arrays["boxes"][:, :1]], axis=1)
    arrays["image_size"] = np.concatenate([arrays["image_size"], arrays["image_size"][:1]])
    path = MomDataset(**arrays).save(tmp_path / "three.npz")
    done = _momloc("eval", str(model), str(path), "--json")
    assert done.returncode == 2
    assert done.stdout == ""
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "3 cameras but the model was trained for 2" in lines[0]


def test_missing_model_dir_is_one_line(tmp_path: Path, trained: tuple[Path, Path]) -> None:
    _, data = trained
    done = _momloc("eval", str(tmp_path / "nope"), str(data))
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "nope" in lines[0] and "Traceback" not in done.stderr


def test_missing_data_file_is_one_line(trained: tuple[Path, Path], tmp_path: Path) -> None:
    model, _ = trained
    done = _momloc("eval", str(model), str(tmp_path / "absent.npz"))
    assert done.returncode == 2
    assert len(done.stderr.strip().splitlines()) == 1 and "no such file" in done.stderr
