"""V4L2 device listing: ioctl numbers, struct parsing against an emulated driver, fall-backs."""

from __future__ import annotations

import errno
import os
import struct

from capture import v4l2


def fourcc(text: str) -> int:
    return sum(ord(c) << (8 * i) for i, c in enumerate(text))


FORMATS = {  # fourcc → (description, {(width, height): [(numerator, denominator) interval]})
    fourcc("MJPG"): ("Motion-JPEG", {(640, 480): [(1, 30), (1, 15)], (1280, 720): [(1, 30)]}),
    fourcc("YUYV"): ("YUYV 4:2:2", {(640, 480): [(1, 30), (1, 5)]}),
}


class FakeDriver:
    """Answers V4L2 ioctls like a UVC webcam (capture node) or its metadata node."""

    def __init__(self, capture: bool = True):
        self.capture = capture
        self.formats = FORMATS

    def __call__(self, fd: int, request: int, buffer: bytearray) -> None:
        if request == v4l2.VIDIOC_QUERYCAP:
            device_caps = 0x04000001 if self.capture else 0x04800000  # streaming + capture/meta
            v4l2.CAPABILITY.pack_into(
                buffer, 0, b"uvcvideo", b"HD Webcam C270", b"usb-0000:00:14.0-2", 0x60800,
                0x84A00001, device_caps,
            )  # fmt: skip
            return
        index = struct.unpack_from("<I", buffer)[0]
        if request == v4l2.VIDIOC_ENUM_FMT:
            codes = list(self.formats)
            if index >= len(codes):
                raise OSError(errno.EINVAL, "Invalid argument")
            code = codes[index]
            v4l2.FMTDESC.pack_into(buffer, 0, index, 1, 1, self.formats[code][0].encode(), code, 0)
        elif request == v4l2.VIDIOC_ENUM_FRAMESIZES:
            code = struct.unpack_from("<I", buffer, 4)[0]
            sizes = list(self.formats[code][1])
            if index >= len(sizes):
                raise OSError(errno.EINVAL, "Invalid argument")
            v4l2.FRMSIZE.pack_into(buffer, 0, index, code, 1, *sizes[index], 0, 0, 0, 0)
        elif request == v4l2.VIDIOC_ENUM_FRAMEINTERVALS:
            code, width, height = struct.unpack_from("<III", buffer, 4)
            rates = self.formats[code][1][(width, height)]
            if index >= len(rates):
                raise OSError(errno.EINVAL, "Invalid argument")
            v4l2.FRMIVAL.pack_into(
                buffer, 0, index, code, width, height, 1, *rates[index], 0, 0, 0, 0
            )
        else:
            raise OSError(errno.ENOTTY, "Inappropriate ioctl for device")


def test_ioctl_numbers_match_the_kernel_headers():
    assert v4l2.VIDIOC_QUERYCAP == 0x80685600
    assert v4l2.VIDIOC_ENUM_FMT == 0xC0405602
    assert v4l2.VIDIOC_ENUM_FRAMESIZES == 0xC02C564A
    assert v4l2.VIDIOC_ENUM_FRAMEINTERVALS == 0xC034564B
    sizes = (v4l2.CAPABILITY.size, v4l2.FMTDESC.size, v4l2.FRMSIZE.size, v4l2.FRMIVAL.size)
    assert sizes == (104, 64, 44, 52)


def test_query_device_reads_formats_sizes_and_rates():
    device = v4l2.query_device(3, "/dev/video0", FakeDriver())
    assert (device.card, device.driver, device.bus) == (
        "HD Webcam C270", "uvcvideo", "usb-0000:00:14.0-2"
    )  # fmt: skip
    assert device.capture
    assert [f.fourcc for f in device.formats] == ["MJPG", "YUYV"]
    mjpg = device.formats[0]
    assert mjpg.description == "Motion-JPEG"
    assert [(s.width, s.height, s.fps) for s in mjpg.sizes] == [
        (640, 480, (30.0, 15.0)),
        (1280, 720, (30.0,)),
    ]
    assert device.formats[1].sizes[0].fps == (30.0, 5.0)


def test_metadata_nodes_are_not_capture_devices():
    device = v4l2.query_device(3, "/dev/video1", FakeDriver(capture=False))
    assert not device.capture and device.formats == []


def test_list_devices_numeric_order_links_and_fallback(tmp_path):
    for name in ("video10", "video2", "video0"):
        (tmp_path / name).write_bytes(b"")
    by_id = tmp_path / "v4l" / "by-id"
    by_id.mkdir(parents=True)
    os.symlink(tmp_path / "video2", by_id / "usb-Logitech_C270-video-index0")
    assert v4l2.device_paths(str(tmp_path)) == [str(tmp_path / f"video{n}") for n in (0, 2, 10)]
    devices = v4l2.list_devices(str(tmp_path), FakeDriver())
    assert [d.card for d in devices] == ["HD Webcam C270"] * 3
    assert devices[1].links == [str(by_id / "usb-Logitech_C270-video-index0")]
    # Real ioctls on a regular file fail (ENOTTY): the device is probed with OpenCV instead.
    fallback = v4l2.list_devices(str(tmp_path), ioctl=_refuse)[0]
    assert fallback.probe == "opencv" and not fallback.capture
    assert fallback.error is not None
    assert "ioctl failed" in fallback.error and "cannot open" in fallback.error


def test_no_devices_gives_an_empty_list(tmp_path):
    assert v4l2.list_devices(str(tmp_path)) == []


def _refuse(fd: int, request: int, buffer: bytearray) -> None:
    raise OSError(errno.ENOTTY, "Inappropriate ioctl for device")
