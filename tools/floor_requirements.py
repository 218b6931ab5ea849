"""Print the declared minimum versions of pyproject.toml as exact pins (``name==floor``).

Used by ``make test-floors``: the floors are a promise that only an install of exactly those
versions can check. Standard library only, so it runs in a fresh virtual environment.
"""

from __future__ import annotations

import re
import sys
import tomllib
from pathlib import Path

FLOOR = re.compile(r"^\s*([A-Za-z0-9_.\-\[\]]+)\s*>=\s*([0-9][A-Za-z0-9.]*)")


def floor_pins(pyproject: Path) -> list[str]:
    """One ``name==version`` per runtime dependency; a dependency without a floor is an error."""
    pins = []
    for text in tomllib.loads(pyproject.read_text())["project"]["dependencies"]:
        match = FLOOR.match(text)
        if match is None:
            raise SystemExit(f"{pyproject}: dependency {text!r} declares no '>=' floor")
        pins.append(f"{match.group(1)}=={match.group(2)}")
    return pins


if __name__ == "__main__":
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent
    print("\n".join(floor_pins(root / "pyproject.toml")))
