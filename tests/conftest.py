"""Fixtures for every test."""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def _no_self_labels_in_the_working_folder(monkeypatch: pytest.MonkeyPatch) -> None:
    """Daemons built from default settings keep self-labels under ``data_dir``
    (``service.learning``), by default ``./momloc-data``: in tests that is the repository. The
    learning room is off unless a test turns it on in its own settings (with its own data_dir);
    the environment reaches ``momloc`` child processes too."""
    monkeypatch.setenv("MOMLOC_LEARNING__ENABLED", "false")
