"""The dependency rule of ARCHITECTURE.md, checked on the source: ``service`` → ``models``,
``capture``; ``models`` never imports ``capture`` or ``service``; ``capture`` gives frames and
imports nothing of the project but two project-wide leaf utilities that happen to live in
``models``: ``models.errors`` (the one user-facing error type) and ``models.atomic`` (the one
atomic file writer, which recordings must use too). Both import nothing of the project, so
they add no path back into ``models``' learned parts. Every import counts, also those inside
functions or under ``TYPE_CHECKING``: a lazy import is still a dependency.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("capture", "models", "service")
# package -> top-level packages of the project it may import (besides itself)
ALLOWED = {"capture": set(), "models": set(), "service": {"capture", "models"}}
# exact modules a package may import although their package is not allowed
LEAF_EXCEPTIONS = {"capture": {"models.errors", "models.atomic"}}


def project_imports(path: Path) -> set[str]:
    """Dotted names of the project modules ``path`` imports (absolute imports only)."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return {n for n in names if n.split(".")[0] in PACKAGES}


def sources(package: str) -> list[Path]:
    return sorted((ROOT / package).rglob("*.py"))


@pytest.mark.parametrize("package", PACKAGES)
def test_packages_import_only_downwards(package: str) -> None:
    broken = []
    for path in sources(package):
        for name in project_imports(path):
            top = name.split(".")[0]
            allowed = top == package or top in ALLOWED[package]
            if not allowed and name not in LEAF_EXCEPTIONS.get(package, set()):
                broken.append(f"{path.relative_to(ROOT)} imports {name}")
    assert not broken, "\n".join(broken)


def test_the_modules_capture_may_use_are_leaves() -> None:
    for name in LEAF_EXCEPTIONS["capture"]:
        path = ROOT / (name.replace(".", "/") + ".py")
        assert project_imports(path) == set(), name


def test_no_cycle_between_top_level_packages() -> None:
    edges = {
        package: {name.split(".")[0] for path in sources(package) for name in project_imports(path)}
        - {package}
        for package in PACKAGES
    }

    def reaches(start: str, goal: str, seen: frozenset[str] = frozenset()) -> bool:
        return any(
            nxt == goal or (nxt not in seen and reaches(nxt, goal, seen | {nxt}))
            for nxt in edges[start]
        )

    cyclic = [package for package in PACKAGES if reaches(package, package)]
    assert not cyclic, f"import cycle through {cyclic}: {edges}"


def test_the_checker_sees_lazy_and_type_checking_imports(tmp_path: Path) -> None:
    module = tmp_path / "m.py"
    module.write_text(
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from service.hub import Hub\n"
        "def f():\n    import models.simulate\n    from . import sibling\n"
    )
    assert project_imports(module) == {"service.hub", "models.simulate"}
