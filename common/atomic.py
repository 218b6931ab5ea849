"""One way to write a file so that a reader never sees it half-written: the project's only one.

Datasets, recordings, model files and settings are read by other processes while they are being
replaced (the daemon hot-reloads ``model.json``; a crash mid-collection must keep the rows already
recorded). Every writer therefore

1. writes into a temporary file in the *same* folder (a rename across file systems is a copy),
2. flushes and ``fsync``s it, so a power cut cannot leave a renamed but empty file,
3. sets the final mode (default 0644: ``mkstemp`` makes files private, but the daemon may run as
   another user than ``momloc train``),
4. renames it over the target in one step (``os.replace``, atomic on POSIX) and ``fsync``s the
   folder so the rename itself is durable,

and removes the temporary file if anything fails, so an error leaves the old file untouched.

Example::

    atomic_write_json(model_dir / "model.json", meta)
    atomic_write(path, lambda tmp: np.savez_compressed(tmp, **arrays))
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

DEFAULT_MODE = 0o644


def atomic_write(
    path: str | os.PathLike[str], produce: Callable[[Path], object], mode: int = DEFAULT_MODE
) -> Path:
    """Replace ``path`` with what ``produce(temporary_path)`` writes, atomically (see above)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        produce(tmp)
        with open(tmp, "rb+") as handle:
            os.fsync(handle.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    _fsync_folder(path.parent)
    return path


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, mode: int = DEFAULT_MODE) -> Path:
    return atomic_write(path, lambda tmp: tmp.write_bytes(data), mode)


def atomic_write_text(path: str | os.PathLike[str], text: str, mode: int = DEFAULT_MODE) -> Path:
    return atomic_write(path, lambda tmp: tmp.write_text(text), mode)


def atomic_write_json(
    path: str | os.PathLike[str], value: Any, mode: int = DEFAULT_MODE, indent: int | None = 1
) -> Path:
    return atomic_write_text(path, json.dumps(value, indent=indent), mode)


def replace_folder(
    staging: str | os.PathLike[str], final: str | os.PathLike[str], keep_as: str = ".previous"
) -> Path:
    """Put a completely written folder (a new model) at ``final``; the old one becomes
    ``<final><keep_as>`` (``.previous`` unless told: the set-up's two-stage training keeps
    its first model as ``.first`` so that ``.previous`` stays the model from before).

    Two renames, not one: POSIX cannot swap a non-empty folder atomically. Between them there
    is briefly no ``final``; the model watcher then keeps serving the model it has loaded, so a
    reader sees the old model or the new one, never a mixture of their files.
    """
    staging, final = Path(staging), Path(final)
    previous = final.with_name(final.name + keep_as)
    if final.exists():
        shutil.rmtree(previous, ignore_errors=True)
        os.replace(final, previous)
    os.replace(staging, final)
    _fsync_folder(final.parent)
    return final


def _fsync_folder(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:  # some file systems do not open folders; the rename still happened
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
