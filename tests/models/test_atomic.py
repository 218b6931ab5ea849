"""The project's one atomic writer: complete file or old file, readable by other users."""

from __future__ import annotations

import json
import stat
from pathlib import Path

import pytest

from common.atomic import atomic_write, atomic_write_json, atomic_write_text, replace_folder


def test_replaces_the_file_whole_with_mode_0644(tmp_path: Path) -> None:
    target = tmp_path / "sub" / "model.json"
    atomic_write_json(target, {"a": 1})
    assert json.loads(target.read_text()) == {"a": 1}
    assert stat.S_IMODE(target.stat().st_mode) == 0o644
    atomic_write_text(target, "second")
    assert target.read_text() == "second"
    assert [p.name for p in target.parent.iterdir()] == ["model.json"]  # no temporary left


def test_a_failing_writer_leaves_the_old_file_and_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "data.npz"
    target.write_text("old")

    def half_then_fail(tmp: Path) -> None:
        tmp.write_text("half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        atomic_write(target, half_then_fail)
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["data.npz"]


def test_mode_can_be_private(tmp_path: Path) -> None:
    target = atomic_write_text(tmp_path / "secret", "x", mode=0o600)
    assert stat.S_IMODE(target.stat().st_mode) == 0o600


def test_replace_folder_installs_the_new_model_and_keeps_one_previous(tmp_path: Path) -> None:
    final = tmp_path / "model"
    for version in ("1", "2", "3"):
        staging = tmp_path / "model.training"
        staging.mkdir()
        (staging / "model.json").write_text(version)
        replace_folder(staging, final)
        assert not staging.exists()
        assert (final / "model.json").read_text() == version
    assert (tmp_path / "model.previous" / "model.json").read_text() == "2"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model", "model.previous"]
