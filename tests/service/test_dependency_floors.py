"""Declared minimum versions (pyproject.toml) cover what the code uses, and this install meets them.

Why: the floors are a promise to users who install into an existing environment. They once
allowed websockets 12 and uvicorn 0.29, which lack ``websockets.asyncio.client`` and uvicorn's
``websockets-sansio`` protocol, so such an install failed at start. This test is cheap (no
install); ``make test-floors`` installs exactly the declared floors and runs the server tests
against them.
"""

from __future__ import annotations

import importlib
import tomllib
from importlib.metadata import version
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.version import Version

PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"

# the oldest release that has what the code uses: (version, what needs it)
NEEDED = {
    "websockets": ("13.0", "websockets.asyncio.client (clients, tests)"),
    "uvicorn": ("0.35.0", 'ws="websockets-sansio" and timeout_graceful_shutdown (daemon)'),
    "fastapi": ("0.110.0", "lifespan=, Annotated parameters, responses= on the app"),
    "pydantic": ("2.6.0", "Field(allow_inf_nan=, strict=), model_validator"),
    "pydantic-settings": ("2.2.0", "settings_customise_sources with a custom source"),
}


def declared_floors() -> dict[str, Version]:
    project = tomllib.loads(PYPROJECT.read_text())["project"]
    floors = {}
    for text in project["dependencies"]:
        requirement = Requirement(text)
        lower = [s.version for s in requirement.specifier if s.operator in (">=", "==", "~=")]
        assert lower, f"{text}: no minimum version declared"
        floors[requirement.name.lower()] = Version(lower[0])
    return floors


def test_declared_floors_cover_what_the_code_uses():
    floors = declared_floors()
    for name, (needed, why) in NEEDED.items():
        assert floors[name] >= Version(needed), f"{name}>={floors[name]} is too old: {why}"


@pytest.mark.parametrize("name", sorted(declared_floors()))
def test_installed_versions_meet_the_declared_floors(name):
    assert Version(version(name)) >= declared_floors()[name]


def test_the_features_the_floors_promise_exist():
    importlib.import_module("websockets.asyncio.client")
    from uvicorn.config import WS_PROTOCOLS

    assert "websockets-sansio" in WS_PROTOCOLS
