"""Fixtures for every test."""

from __future__ import annotations

from collections.abc import Iterator

import pytest


@pytest.fixture(autouse=True, scope="session")
def _no_self_labels_in_the_working_folder() -> Iterator[None]:
    """Daemons built from default settings keep self-labels under ``data_dir``
    (``service.learning``), by default ``./momloc-data``: in tests that is the repository. The
    learning room is off unless a test turns it on in its own settings (with its own data_dir);
    the environment reaches ``momloc`` child processes too. Session-scoped, so that module-scoped
    servers (built before any function-scoped fixture) see it as well."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("MOMLOC_LEARNING__ENABLED", "false")
        yield
