"""The one line ``make test-docker-arm64`` skips with names what the machine lacks: binfmt_misc
itself, QEMU's handler, the handler switched on, its F flag (read from a fake binfmt_misc)."""

from __future__ import annotations

import platform

import pytest

from tests.e2e.docker_engine import arm64_emulation_missing

HANDLER = (
    "enabled\ninterpreter /usr/libexec/qemu-binfmt/aarch64-binfmt-P\nflags: {flags}\noffset 0\n"
    "magic 7f454c460201010000000000000000000200b700\n"
)


@pytest.fixture(autouse=True)
def _on_x86(monkeypatch):
    monkeypatch.setattr(platform, "machine", lambda: "x86_64")


def test_unmounted_binfmt_misc(tmp_path):
    assert "binfmt_misc is not mounted" in str(arm64_emulation_missing(tmp_path))


def test_no_qemu_handler(tmp_path):
    (tmp_path / "register").touch()
    assert "no qemu-aarch64 handler" in str(arm64_emulation_missing(tmp_path))


def test_disabled_handler(tmp_path):
    (tmp_path / "register").touch()
    (tmp_path / "qemu-aarch64").write_text(
        HANDLER.format(flags="PF").replace("enabled", "disabled")
    )
    assert "handler is disabled" in str(arm64_emulation_missing(tmp_path))


def test_handler_without_the_fix_binary_flag(tmp_path):
    (tmp_path / "register").touch()
    (tmp_path / "qemu-aarch64").write_text(HANDLER.format(flags="P"))
    assert "lacks the F flag" in str(arm64_emulation_missing(tmp_path))


def test_qemu_user_static_handler_emulates(tmp_path):
    (tmp_path / "register").touch()
    (tmp_path / "qemu-aarch64").write_text(HANDLER.format(flags="PF"))
    assert arm64_emulation_missing(tmp_path) is None


def test_an_arm64_machine_needs_no_emulation(tmp_path, monkeypatch):
    monkeypatch.setattr(platform, "machine", lambda: "aarch64")
    assert arm64_emulation_missing(tmp_path) is None
