"""Debian packages for e2e tests, installed on first use (chromium, mosquitto, mono, ...).

The tests need real services and toolchains, and a fresh machine has none of them: the test set-up
installs them from Debian once, and skips the test with the reason when that is impossible (no
apt-get, no route to the Debian mirror), so ``make test`` stays the only command a user runs.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

APT_ENV = {"DEBIAN_FRONTEND": "noninteractive", "PATH": "/usr/sbin:/usr/bin:/sbin:/bin"}


def _present(binary: str) -> bool:
    """A bare name is looked up on PATH; an absolute path (e.g. /usr/sbin/...) must exist."""
    return Path(binary).exists() if "/" in binary else shutil.which(binary) is not None


def ensure_debian(
    binaries: tuple[str, ...], packages: tuple[str, ...], *, recommends: bool = False
) -> None:
    """Make ``binaries`` available, installing ``packages`` with apt-get if one is missing.

    ``recommends`` keeps Debian's recommended packages (chromium wants its fonts for readable
    screenshots); toolchains skip them to keep the install small.
    """
    if all(_present(b) for b in binaries):
        return
    if shutil.which("apt-get") is None:
        pytest.skip(f"{', '.join(binaries)} missing and apt-get is not available to install it")
    install = ["apt-get", "install", "-y", *([] if recommends else ["--no-install-recommends"])]
    for step in (["apt-get", "update"], [*install, *packages]):
        result = subprocess.run(step, capture_output=True, text=True, timeout=900, env=APT_ENV)
        if result.returncode != 0:
            tail = (result.stderr or result.stdout).strip().splitlines()[-1:] or ["no output"]
            pytest.skip(f"cannot install {' '.join(packages)} ({' '.join(step[:2])}: {tail[0]})")
    missing = [b for b in binaries if not _present(b)]
    if missing:
        pytest.skip(f"installed {' '.join(packages)} but {', '.join(missing)} is still missing")
