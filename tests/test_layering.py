"""The dependency rules of the architecture (docs: development/architecture), checked on the source.

Between top-level packages: ``service`` → ``models``, ``capture``, ``common``; ``models`` and
``capture`` import only ``common`` (the leaf helpers: the one error type, the one atomic writer,
the one onnxruntime session); ``common`` imports nothing of the project.

Inside ``service`` each subpackage lists the others it may use, so the folders read as layers:
the live ``pipeline`` never reaches up into the API, the set-up flow, the outputs or the offline
commands; ``tracking`` and ``detection`` know only the typed values between stages
(``service.stages``, ``service.snapshot``); outputs only consume snapshots. The composition
root (``service.daemon``, ``service.demo``), the CLI and its commands may import anything.

Inside ``models`` torch is a folder rule: only ``models.mom.training`` imports torch or onnx, so
serving (everything else) cannot load it by accident.

Every import counts, also those inside functions or under ``TYPE_CHECKING``: a lazy import is
still a dependency.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("capture", "common", "models", "service")
# top-level package -> the project's top-level packages it may import (besides itself)
ALLOWED = {
    "common": set(),
    "capture": {"common"},
    "models": {"common"},
    "service": {"capture", "common", "models"},
}
# service part -> the other service parts it may import; parts not listed may import anything
SERVICE_ALLOWED = {
    "snapshot": set(),
    "stages": {"snapshot"},
    "camera_health": {"stages", "snapshot"},
    "tracking": {"stages", "snapshot"},
    "outputs": {"snapshot"},
    "detection": {"stages", "snapshot", "settings"},
    "settings": {"outputs", "tracking"},
    "pipeline": {"stages", "snapshot", "settings", "tracking", "detection", "camera_health"},
    "setup": {"stages", "snapshot", "settings", "pipeline"},
    "offline": {
        "stages",
        "snapshot",
        "settings",
        "pipeline",
        "tracking",
        "detection",
        "setup",
        "stop_signals",
    },
    "learning": {"stages", "snapshot", "settings", "setup", "camera_health"},
    "api": {
        "stages",
        "snapshot",
        "settings",
        "pipeline",
        "outputs",
        "setup",
        "camera_health",
        "learning",
    },
}
# models part -> the other models parts it may import
MODELS_ALLOWED = {
    "data": set(),
    "detector": set(),
    "geometry": {"data"},
    "simulate": {"data", "detector"},
    "mom": {"data", "geometry"},
}
TRAINING_ONLY = {"torch", "onnx"}


def project_imports(path: Path) -> set[str]:
    """Dotted names of the modules ``path`` imports (absolute imports only)."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


def sources(package: str) -> list[Path]:
    return sorted((ROOT / package).rglob("*.py"))


def module_name(path: Path) -> str:
    return ".".join(path.relative_to(ROOT).with_suffix("").parts)


def part(name: str) -> str:
    """``service.tracking.tracker`` -> ``tracking``; ``service.settings`` -> ``settings``."""
    parts = name.split(".")
    return parts[1] if len(parts) > 1 else ""


@pytest.mark.parametrize("package", PACKAGES)
def test_packages_import_only_downwards(package: str) -> None:
    broken = []
    for path in sources(package):
        for name in project_imports(path):
            top = name.split(".")[0]
            if top in PACKAGES and top != package and top not in ALLOWED[package]:
                broken.append(f"{path.relative_to(ROOT)} imports {name}")
    assert not broken, "\n".join(broken)


@pytest.mark.parametrize(
    ("package", "rules"), [("service", SERVICE_ALLOWED), ("models", MODELS_ALLOWED)]
)
def test_parts_import_only_the_parts_they_list(package: str, rules: dict[str, set[str]]) -> None:
    broken = []
    for path in sources(package):
        source = part(module_name(path))
        if source not in rules:
            continue
        for name in project_imports(path):
            if name.split(".")[0] != package:
                continue
            target = part(name)
            if target and target != source and target not in rules[source]:
                broken.append(f"{path.relative_to(ROOT)} imports {name}")
    assert not broken, "\n".join(broken)


def test_only_training_imports_torch() -> None:
    broken = [
        f"{path.relative_to(ROOT)} imports {name}"
        for package in PACKAGES
        for path in sources(package)
        if not module_name(path).startswith("models.mom.training")
        for name in project_imports(path)
        if name.split(".")[0] in TRAINING_ONLY
    ]
    assert not broken, "\n".join(broken)


def test_serving_parts_never_import_training() -> None:
    broken = [
        f"{path.relative_to(ROOT)} imports {name}"
        for package in ("capture", "common", "models", "service")
        for path in sources(package)
        if not module_name(path).startswith(("models.mom.training", "service.commands"))
        for name in project_imports(path)
        if name.startswith("models.mom.training")
    ]
    assert not broken, "\n".join(broken)


def test_no_cycle_between_service_parts() -> None:
    edges: dict[str, set[str]] = {}
    for path in sources("service"):
        source = part(module_name(path))
        for name in project_imports(path):
            if name.split(".")[0] == "service" and part(name) not in ("", source):
                edges.setdefault(source, set()).add(part(name))

    def reaches(start: str, goal: str, seen: frozenset[str] = frozenset()) -> bool:
        return any(
            nxt == goal or (nxt not in seen and reaches(nxt, goal, seen | {nxt}))
            for nxt in edges.get(start, ())
        )

    cyclic = sorted(p for p in edges if reaches(p, p))
    assert not cyclic, f"import cycle through {cyclic}: {edges}"


def test_the_checker_sees_lazy_and_type_checking_imports(tmp_path: Path) -> None:
    module = tmp_path / "m.py"
    module.write_text(
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from service.pipeline.hub import Hub\n"
        "def f():\n    import models.simulate\n    from . import sibling\n"
    )
    assert project_imports(module) == {"typing", "service.pipeline.hub", "models.simulate"}
