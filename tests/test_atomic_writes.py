"""One atomic writer for the whole project (``common/atomic.py``): no module renames or makes
temporary files itself, and the files it writes are readable by others (mode 0644)."""

from __future__ import annotations

import ast
import stat
from pathlib import Path

import numpy as np

from models.data.dataset import MomDataset
from service.setup.collector import DatasetAppender, collect, plan_steps, progress_path
from service.setup.feeds import FeedFrame
from service.setup.marks import FloorMark
from tests.service.setup.test_collector import BOX, SIZES, ListFeed

ROOT = Path(__file__).resolve().parents[1]
WRITER = ROOT / "common" / "atomic.py"
# what only the atomic writer may call: a rename over a target, a temporary file beside it
RESERVED = {("os", "replace"), ("os", "rename"), ("tempfile", "mkstemp")}
RESERVED_NAMES = {"NamedTemporaryFile", "mkstemp"}


def reserved_calls(path: Path) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name):
            if (func.value.id, func.attr) in RESERVED or func.attr in RESERVED_NAMES:
                found.append(f"{path.relative_to(ROOT)}:{node.lineno} {func.value.id}.{func.attr}")
        elif isinstance(func, ast.Name) and func.id in RESERVED_NAMES:
            found.append(f"{path.relative_to(ROOT)}:{node.lineno} {func.id}")
    return found


def test_only_common_atomic_renames_or_makes_temporary_files() -> None:
    files = [
        p
        for pkg in ("capture", "common", "models", "service", "tools")
        for p in (ROOT / pkg).rglob("*.py")
    ]
    copies = [hit for path in files if path != WRITER for hit in reserved_calls(path)]
    assert not copies, "atomic-write copies (use common.atomic):\n" + "\n".join(copies)
    assert reserved_calls(WRITER)  # the scan does see the one writer's calls


def test_collected_data_and_progress_files_are_readable_by_others(tmp_path: Path) -> None:
    out = tmp_path / "marks.npz"
    steps = plan_steps([FloorMark("a", 1, 2)], 2, start=(1, 2))
    collect(ListFeed(FeedFrame(0, [BOX, BOX])), steps, DatasetAppender(out, SIZES))
    assert MomDataset.load(out).n > 0
    for path in (out, progress_path(out)):
        assert stat.S_IMODE(path.stat().st_mode) == 0o644, path.name
    np.testing.assert_allclose(MomDataset.load(out).world[0], [1, 2])
