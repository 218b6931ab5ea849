"""Training: it learns, splits without leakage, is reproducible, refuses bad inputs."""

import json

import numpy as np
import pytest

from common.errors import MomlocError
from models.mom.training.train import adaptive_settings, split_rows, train_model
from service.cli import main
from tests.models.mom_scene import make_dataset, trained_model


def test_training_learns_the_scene():
    out, data, metrics = trained_model()
    spread = np.linalg.norm(data.world - data.world.mean(axis=0), axis=1).mean()
    assert metrics["val_mean_m"] < 0.25 < spread  # far better than guessing the centre
    meta = json.loads((out / "model.json").read_text())
    assert meta["metrics"]["val_mean_m"] == metrics["val_mean_m"]
    assert (out / "encoder.onnx").is_file() and (out / "model.pt").is_file()


def test_split_keeps_runs_together_and_sizes_sane():
    data, _ = make_dataset(1000, seed=2)
    train, val = split_rows(data, 0.15, seed=0)
    assert len(np.intersect1d(train, val)) == 0 and len(train) + len(val) == data.n
    assert 0.08 < len(val) / data.n < 0.3
    # validation rows come in runs of consecutive frames of one track
    order = np.lexsort((data.frame[val], data.track[val]))
    gaps = np.diff(data.frame[val][order])[np.diff(data.track[val][order]) == 0]
    assert (gaps == 1).mean() > 0.8


def test_adaptive_sizes_grow_with_data():
    small, large = adaptive_settings(500, 2), adaptive_settings(80000, 9)
    assert small.batch_size < large.batch_size and small.global_width < large.global_width
    assert small.max_epochs >= large.max_epochs


def test_same_seed_same_model(tmp_path):
    data, _ = make_dataset(300, seed=5)
    a = train_model(data, tmp_path / "a", epochs=3, seed=7, progress=False)
    b = train_model(data, tmp_path / "b", epochs=3, seed=7, progress=False)
    assert a["val_history"] == b["val_history"]


def test_user_errors(tmp_path):
    data, _ = make_dataset(300, seed=5)
    with pytest.raises(MomlocError, match="keypoints"):
        train_model(data, tmp_path / "k", observation="keypoints", progress=False)
    with pytest.raises(MomlocError, match="at least"):
        train_model(data.subset(np.arange(10)), tmp_path / "s", progress=False)


def test_cli_train_writes_a_model(tmp_path, capsys):
    data, _ = make_dataset(300, seed=6)
    path = data.save(tmp_path / "data.npz")
    code = main(["train", str(path), "--out", str(tmp_path / "m"), "--epochs", "2", "--quiet"])
    assert code == 0
    assert "val_mean_m" in json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    bad = tmp_path / "bad.npz"
    bad.write_text("not a zip")
    assert main(["train", str(bad), "--out", str(tmp_path / "x"), "--quiet"]) == 2
    assert (
        main(
            [
                "train",
                str(path),
                "--out",
                str(tmp_path / "y"),
                "--observation",
                "keypoints",
                "--quiet",
            ]
        )
        == 2
    )


def test_each_model_file_is_written_once_complete_and_readable_by_others(tmp_path, monkeypatch):
    """The daemon's model watcher must never load an intermediate model.json (written first
    without, then with the floor prior), and it may run as another user (mode 0644)."""
    import stat

    import models.mom.training.export

    writes: list[str] = []
    real = models.mom.training.export.atomic_write_json
    written = {}

    def counting(path, value, *args, **kwargs):
        writes.append(path.name)
        assert "floor_prior" in value  # complete on its first and only write
        out = real(path, value, *args, **kwargs)
        written[path.name] = (path.stat().st_ino, path.stat().st_mtime_ns)
        return out

    monkeypatch.setattr(models.mom.training.export, "atomic_write_json", counting)
    data, _ = make_dataset(300, seed=5)
    train_model(data, tmp_path / "m", epochs=2, seed=1, progress=False, extra_meta={"note": 1})
    assert writes == ["model.json"]
    final = tmp_path / "m" / "model.json"
    # no other route (a rename over it, a rewrite in place) touched it after that one write
    assert (final.stat().st_ino, final.stat().st_mtime_ns) == written["model.json"]
    assert json.loads(final.read_text())["note"] == 1  # extra entries ride in the one write
    for name in ("model.json", "encoder.onnx", "model.pt"):
        assert stat.S_IMODE((tmp_path / "m" / name).stat().st_mode) == 0o644
    assert sorted(p.name for p in (tmp_path / "m").iterdir()) == [
        "encoder.onnx",
        "model.json",
        "model.pt",
    ]


def test_progress_lines_carry_the_validation_mean_and_median(tmp_path, capsys):
    """The /setup page shows the median: rows whose only box is a false box set the mean."""
    data, _ = make_dataset(300, seed=6)
    path = data.save(tmp_path / "data.npz")
    args = ["train", str(path), "--out", str(tmp_path / "m"), "--epochs", "3", "--quiet"]
    assert main([*args, "--progress-json"]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.strip().splitlines()]
    epochs = [line for line in lines if "epoch" in line]
    assert [line["epoch"] for line in epochs] == [1, 2, 3]
    assert all(line["val_median_m"] > 0 and line["val_error_m"] > 0 for line in epochs)
    best = min(epochs, key=lambda line: line["val_error_m"])  # the model kept
    assert lines[-1]["val_median_m"] == pytest.approx(best["val_median_m"], abs=0.02)
