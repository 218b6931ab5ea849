"""Where the check step's result is kept: never in a file the daemon did not write itself.

The check's summary ("median 0.09 m over 4 marks") belongs with the model it describes. The model
the ``/setup`` page trained lives in ``data_dir/model``, the daemon's own files: the summary goes
into its ``model.json`` (key ``verification``, atomic rewrite) and travels with the model. Any
other model (the demo model shipped inside the installed package, a folder given as
``model_dir``, perhaps read-only or shared) is not the daemon's to change: ``POST
/v1/setup/verify`` on ``momloc demo`` used to rewrite the package's ``models/demo_model/
model.json``. Their summary goes to ``data_dir/checks/<digest>.json`` instead, named by the
SHA-256 of the model's ``model.json``, so a check belongs to those exact model files: a model
retrained in the same folder does not inherit the former one's figure.

Reading (``/v1/health`` ``model.verification``, shown on the map and the set-up page) takes the
``data_dir`` file first (this daemon's latest check of these files), else ``model.json``'s own.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from common.atomic import atomic_write_json

CHECKS = "checks"


def owned(model_dir: Path, data_dir: Path) -> bool:
    """Whether ``model_dir`` is the daemon's own (inside ``data_dir``, where /setup trains)."""
    return Path(model_dir).resolve().is_relative_to(Path(data_dir).resolve())


def check_path(model_dir: Path, data_dir: Path) -> Path:
    """``data_dir/checks/<first 16 hex digits of the SHA-256 of model.json>.json``."""
    digest = hashlib.sha256((Path(model_dir) / "model.json").read_bytes()).hexdigest()[:16]
    return Path(data_dir) / CHECKS / f"{digest}.json"


def store_check(summary: dict[str, Any], model_dir: Path, data_dir: Path) -> Path:
    """Keep ``summary`` for the model in ``model_dir`` (see the module docstring); its path."""
    meta_path = Path(model_dir) / "model.json"
    if owned(model_dir, data_dir):
        meta = json.loads(meta_path.read_text())
        meta["verification"] = summary
        return atomic_write_json(meta_path, meta)
    record = {"model_dir": str(model_dir), "verification": summary}
    return atomic_write_json(check_path(model_dir, data_dir), record)


_read_cache: dict[tuple[Path, Path], tuple[tuple[int, int], dict[str, Any] | None]] = {}


def stored_check(model_dir: Path | None, data_dir: Path) -> dict[str, Any] | None:
    """The summary kept for the model in ``model_dir``, if any.

    Read again only when ``model.json`` or the checks folder changed: ``/v1/health`` asks every
    second and ``model.json`` is tens of kB.
    """
    if model_dir is None:
        return None
    meta_path, checks = Path(model_dir) / "model.json", Path(data_dir) / CHECKS
    try:
        stamp = (meta_path.stat().st_mtime_ns, _mtime(checks))
        key = (meta_path, checks)
        cached = _read_cache.get(key)
        if cached is not None and cached[0] == stamp:
            return cached[1]
        value = _verification(_read(check_path(model_dir, data_dir))) or _verification(
            _read(meta_path)
        )
    except OSError:
        return None
    _read_cache.clear()  # one model is served at a time
    _read_cache[key] = (stamp, value)
    return value


def _mtime(path: Path) -> int:
    try:
        return path.stat().st_mtime_ns  # a new check file changes its folder's time
    except OSError:
        return 0


def _read(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _verification(data: Any) -> dict[str, Any] | None:
    value = data.get("verification") if isinstance(data, dict) else None
    return value if isinstance(value, dict) else None
