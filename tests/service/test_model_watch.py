"""Hot reload watcher: acts once files are stable, reports refusals, does not retry them."""

from __future__ import annotations

import os
from pathlib import Path

from common.errors import MomlocError
from service.pipeline.model_watch import ModelWatcher


class FakePipeline:
    def __init__(self, model_dir: Path, refuse: bool = False) -> None:
        self.model_dir: Path | None = model_dir
        self.refuse, self.reloads = refuse, 0

    def reload_model(self, model_dir: Path | None) -> dict[str, str]:
        self.reloads += 1
        if self.refuse:
            raise MomlocError(
                "model expects 3 cameras, 2 are configured; keeping the current model"
            )
        return {"path": str(model_dir)}


def _write(model_dir: Path, text: str, stamp: int) -> None:
    for name in ("encoder.onnx", "model.json"):
        path = model_dir / name
        path.write_text(text)
        os.utime(path, ns=(stamp, stamp))


def test_reloads_after_files_settle(tmp_path: Path) -> None:
    _write(tmp_path, "v1", 1_000_000_000)
    pipeline = FakePipeline(tmp_path)
    watcher = ModelWatcher(pipeline)
    watcher.poll()
    assert pipeline.reloads == 0  # nothing changed
    _write(tmp_path, "v2-longer", 2_000_000_000)
    watcher.poll()
    assert pipeline.reloads == 0  # changed: wait one poll in case it is still being written
    watcher.poll()
    assert pipeline.reloads == 1 and watcher.last_reload is not None
    assert watcher.last_reload["ok"]
    watcher.poll()
    assert pipeline.reloads == 1


def test_refused_model_is_reported_once(tmp_path: Path) -> None:
    _write(tmp_path, "v1", 1_000_000_000)
    pipeline = FakePipeline(tmp_path, refuse=True)
    watcher = ModelWatcher(pipeline)
    _write(tmp_path, "v2-bad", 2_000_000_000)
    for _ in range(4):
        watcher.poll()
    assert pipeline.reloads == 1
    assert watcher.last_reload is not None and not watcher.last_reload["ok"]
    assert "3 cameras" in watcher.last_reload["error"]


def test_missing_files_do_nothing(tmp_path: Path) -> None:
    pipeline = FakePipeline(tmp_path / "absent")
    watcher = ModelWatcher(pipeline)
    watcher.poll()
    watcher.poll()
    assert pipeline.reloads == 0
