"""Import layering of the daemon: the routes never import the composition root.

``service.daemon`` builds everything and ``service.api.server`` serves it; ``service.api.app`` (the
routes) reads the daemon's state only (``service.api.state``). Before, ``app`` imported ``daemon``
for the state class while ``daemon`` imported ``app`` to serve it: a cycle that only worked
because one side imported late. Each check runs in a fresh interpreter, so modules loaded by
other tests cannot hide an import.
"""

from __future__ import annotations

import subprocess
import sys

import pytest


def loaded_after(statement: str) -> set[str]:
    script = f"import sys\n{statement}\nprint(' '.join(sorted(sys.modules)))"
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr
    return set(result.stdout.split())


@pytest.mark.parametrize(
    ("module", "must_not_load"),
    [
        ("service.api.app", {"service.daemon", "service.api.server"}),
        ("service.api.state", {"service.daemon", "service.api.server", "service.api.app"}),
        ("service.daemon", {"service.api.server", "service.api.app"}),
        ("service.pipeline.live", {"service.daemon", "service.api.server", "service.api.app"}),
        (
            "service.stages",
            {"service.pipeline.live", "service.tracking.association", "service.daemon"},
        ),
    ],
)
def test_module_does_not_import_upward(module: str, must_not_load: set[str]) -> None:
    loaded = loaded_after(f"import {module}")
    assert module in loaded
    assert not loaded & must_not_load, sorted(loaded & must_not_load)
