"""The settings reference page is generated from the settings schema and never stale."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest
from pydantic import BaseModel

from service.settings import Settings

ROOT = Path(__file__).resolve().parents[2]
TOOL = ROOT / "tools" / "settings_reference.py"


def _tool() -> ModuleType:
    spec = importlib.util.spec_from_file_location("settings_reference", TOOL)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_committed_page_is_what_the_tool_writes() -> None:
    """Fails when a setting or its description changed without re-running the tool."""
    result = subprocess.run(
        [sys.executable, str(TOOL), "--check"], capture_output=True, text=True, cwd=ROOT
    )
    assert result.returncode == 0, result.stdout + result.stderr


def test_check_reports_a_stale_page_and_a_rewrite_fixes_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    tool = _tool()
    page = tmp_path / "settings.md"
    page.write_text(tool.render().replace("Bind address", "Bound address"))
    monkeypatch.setattr(tool, "PAGE", page)
    monkeypatch.setattr(tool, "ROOT", tmp_path)
    assert tool.main(["--check"]) == 1
    assert tool.main([]) == 0
    assert tool.main(["--check"]) == 0
    assert "Bind address" in page.read_text()


def _every_field(model: type[BaseModel], prefix: str = "") -> list[tuple[str, str | None]]:
    fields: list[tuple[str, str | None]] = []
    tool = _tool()
    for name, field in model.model_fields.items():
        fields.append((prefix + name, field.description))
        for child in tool._models_in(field.annotation):
            fields += _every_field(child, f"{prefix}{name}.")
    return fields


def test_every_setting_is_described_and_on_the_page() -> None:
    page = _tool().render()
    for key, description in _every_field(Settings):
        assert description, f"{key}: Field(description=...) missing"
        assert f"| `{key.rsplit('.', 1)[-1]}` |" in page, key
