"""``service.setup.check_store``: a check result goes into the daemon's own model only."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from service.settings import DEMO_MODEL_DIR
from service.setup.check_store import store_check, stored_check

SUMMARY = {"marks": 2, "median_m": 0.12, "text": "median 0.12 m over 2 marks"}


def _model(folder: Path) -> Path:
    folder.mkdir(parents=True)
    shutil.copy(DEMO_MODEL_DIR / "model.json", folder / "model.json")
    return folder


def test_the_daemons_own_model_keeps_its_result_in_model_json(tmp_path: Path) -> None:
    data_dir = tmp_path / "data"
    model = _model(data_dir / "model")  # where /setup trains
    stored = store_check(SUMMARY, model, data_dir)
    assert stored == model / "model.json"
    assert json.loads(stored.read_text())["verification"] == SUMMARY
    assert stored_check(model, data_dir) == SUMMARY
    assert not (data_dir / "checks").exists()


def test_another_model_is_left_alone_and_a_retrained_one_has_no_result(tmp_path: Path) -> None:
    data_dir, model = tmp_path / "data", _model(tmp_path / "elsewhere")
    before = (model / "model.json").read_bytes()
    stored = store_check(SUMMARY, model, data_dir)
    assert stored.parent == data_dir / "checks"
    assert (model / "model.json").read_bytes() == before
    assert stored_check(model, data_dir) == SUMMARY

    meta = json.loads(before)
    meta["metrics"] = {"retrained": True}  # new model files in the same folder
    (model / "model.json").write_text(json.dumps(meta))
    assert stored_check(model, data_dir) is None
    assert stored_check(None, data_dir) is None
