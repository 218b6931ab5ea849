"""`momloc cameras` through the real CLI entry point."""

from __future__ import annotations

import json

from capture import v4l2
from service.cli import main
from tests.capture.test_v4l2 import FakeDriver


def test_says_clearly_when_there_are_no_cameras(tmp_path, capsys):
    assert main(["cameras", "--dev-root", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "No V4L2 cameras found" in out and "video*" in out
    assert main(["cameras", "--json", "--dev-root", str(tmp_path)]) == 0
    assert json.loads(capsys.readouterr().out) == []


def test_lists_devices_formats_and_stable_names(tmp_path, capsys, monkeypatch):
    (tmp_path / "video0").write_bytes(b"")
    (tmp_path / "v4l" / "by-id").mkdir(parents=True)
    (tmp_path / "v4l" / "by-id" / "usb-cam-video-index0").symlink_to(tmp_path / "video0")
    real = v4l2.list_devices
    monkeypatch.setattr(v4l2, "list_devices", lambda root: real(root, FakeDriver()))
    assert main(["cameras", "--dev-root", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "video0  HD Webcam C270 (uvcvideo, usb-0000:00:14.0-2)" in out
    assert "stable name: " in out and "usb-cam-video-index0" in out
    assert "MJPG  Motion-JPEG: 640x480 @ 30/15 fps, 1280x720 @ 30 fps" in out
    assert "MJPG 640x480 @ 30 fps: yes" in out
    assert main(["cameras", "--json", "--dev-root", str(tmp_path)]) == 0
    (listed,) = json.loads(capsys.readouterr().out)
    assert listed["formats"][0]["fourcc"] == "MJPG"
