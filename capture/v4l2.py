"""List V4L2 video devices and the formats they offer, for ``momloc cameras``.

Why raw ioctls: they need nothing installed (no ``v4l2-ctl``), never start streaming, and show
what the driver really offers (pixel formats, discrete sizes, frame rates), which is what a user
needs to choose MJPG 640×480 at 30 fps. Where an ioctl fails (an unusual driver, no permission)
the device is probed through OpenCV instead, which at least tells whether MJPG 640×480 opens.

Structures (``linux/videodev2.h``): ``v4l2_capability`` 104 bytes, ``v4l2_fmtdesc`` 64,
``v4l2_frmsizeenum`` 44, ``v4l2_frmivalenum`` 52. Enumerations end with ``EINVAL``.
"""

from __future__ import annotations

import errno
import glob
import os
import re
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

IoctlFn = Callable[[int, int, bytearray], None]


def _iowr(nr: int, size: int, read_only: bool = False) -> int:
    direction = 2 if read_only else 3  # _IOR / _IOWR
    return (direction << 30) | (size << 16) | (ord("V") << 8) | nr


CAPABILITY = struct.Struct("<16s32s32sIII12x")
FMTDESC = struct.Struct("<III32sII12x")
FRMSIZE = struct.Struct("<III6I8x")
FRMIVAL = struct.Struct("<IIIII6I8x")
VIDIOC_QUERYCAP = _iowr(0, CAPABILITY.size, read_only=True)
VIDIOC_ENUM_FMT = _iowr(2, FMTDESC.size)
VIDIOC_ENUM_FRAMESIZES = _iowr(74, FRMSIZE.size)
VIDIOC_ENUM_FRAMEINTERVALS = _iowr(75, FRMIVAL.size)
BUF_TYPE_VIDEO_CAPTURE = 1
CAP_VIDEO_CAPTURE = 0x00000001
CAP_DEVICE_CAPS = 0x80000000
FRMSIZE_DISCRETE = 1
FRMIVAL_DISCRETE = 1
MAX_ENTRIES = 64  # guards against drivers that never return EINVAL


@dataclass(frozen=True)
class FrameSize:
    width: int
    height: int
    fps: tuple[float, ...] = ()
    stepwise: bool = False  # width/height are then the maximum of a range


@dataclass(frozen=True)
class PixelFormat:
    fourcc: str
    description: str
    sizes: tuple[FrameSize, ...] = ()


@dataclass
class VideoDevice:
    path: str
    card: str = ""
    driver: str = ""
    bus: str = ""
    capture: bool = True
    formats: list[PixelFormat] = field(default_factory=list)
    links: list[str] = field(default_factory=list)  # stable /dev/v4l/by-id, by-path names
    probe: str = "ioctl"
    error: str | None = None


def fourcc_text(code: int) -> str:
    return "".join(chr((code >> (8 * i)) & 0xFF) for i in range(4)).strip()


def _cstr(raw: bytes) -> str:
    return raw.split(b"\0", 1)[0].decode("utf-8", "replace")


def _ioctl(fd: int, request: int, buffer: bytearray) -> None:
    import fcntl

    fcntl.ioctl(fd, request, buffer, True)


def _enumerate(
    ioctl: IoctlFn, fd: int, layout: struct.Struct, request: int, fields: tuple[int, ...]
) -> Iterator[tuple[Any, ...]]:
    """Yield unpacked structs for index 0, 1, ... until the driver answers EINVAL."""
    for index in range(MAX_ENTRIES):
        buffer = bytearray(layout.size)
        struct.pack_into(f"<{1 + len(fields)}I", buffer, 0, index, *fields)
        try:
            ioctl(fd, request, buffer)
        except OSError as error:
            if error.errno == errno.EINVAL:
                return
            raise
        yield layout.unpack(buffer)


def query_device(fd: int, path: str, ioctl: IoctlFn = _ioctl) -> VideoDevice:
    """Capabilities and every capture format, size and frame rate of one open device."""
    buffer = bytearray(CAPABILITY.size)
    ioctl(fd, VIDIOC_QUERYCAP, buffer)
    driver, card, bus, _version, caps, device_caps = CAPABILITY.unpack(buffer)
    effective = device_caps if caps & CAP_DEVICE_CAPS else caps
    device = VideoDevice(path, _cstr(card), _cstr(driver), _cstr(bus))
    device.capture = bool(effective & CAP_VIDEO_CAPTURE)
    if not device.capture:
        return device
    for _i, _t, _flags, desc, pixfmt, _mbus in _enumerate(
        ioctl, fd, FMTDESC, VIDIOC_ENUM_FMT, (BUF_TYPE_VIDEO_CAPTURE,)
    ):
        sizes = []
        for entry in _enumerate(ioctl, fd, FRMSIZE, VIDIOC_ENUM_FRAMESIZES, (pixfmt,)):
            kind, values = entry[2], entry[3:]
            if kind == FRMSIZE_DISCRETE:
                width, height = values[0], values[1]
                sizes.append(FrameSize(width, height, _rates(ioctl, fd, pixfmt, width, height)))
            else:  # continuous / stepwise: report the maximum size
                sizes.append(FrameSize(values[1], values[4], stepwise=True))
        device.formats.append(PixelFormat(fourcc_text(pixfmt), _cstr(desc), tuple(sizes)))
    return device


def _rates(ioctl: IoctlFn, fd: int, pixfmt: int, width: int, height: int) -> tuple[float, ...]:
    rates = []
    for entry in _enumerate(
        ioctl, fd, FRMIVAL, VIDIOC_ENUM_FRAMEINTERVALS, (pixfmt, width, height)
    ):
        kind, numerator, denominator = entry[4], entry[5], entry[6]
        if kind == FRMIVAL_DISCRETE and numerator:
            rates.append(round(denominator / numerator, 2))
    return tuple(sorted(set(rates), reverse=True))


def device_paths(root: str = "/dev") -> list[str]:
    """``/dev/videoN`` in numeric order."""
    paths = glob.glob(os.path.join(root, "video*"))
    return sorted(paths, key=lambda p: int(m.group()) if (m := re.search(r"\d+$", p)) else -1)


def stable_links(root: str = "/dev") -> dict[str, list[str]]:
    """Map each real device path to its ``/dev/v4l/by-id`` and ``by-path`` symlinks."""
    links: dict[str, list[str]] = {}
    for link in sorted(glob.glob(os.path.join(root, "v4l", "by-*", "*"))):
        links.setdefault(os.path.realpath(link), []).append(link)
    return links


def list_devices(root: str = "/dev", ioctl: IoctlFn = _ioctl) -> list[VideoDevice]:
    """Every ``/dev/video*`` with its formats (ioctl), falling back to OpenCV probing."""
    links = stable_links(root)
    devices = []
    for path in device_paths(root):
        try:
            fd = os.open(path, os.O_RDWR | os.O_NONBLOCK)
        except OSError as error:
            devices.append(VideoDevice(path, error=f"cannot open: {error.strerror}"))
            continue
        try:
            device = query_device(fd, path, ioctl)
        except OSError as error:
            device = probe_with_opencv(path)
            probe = device.error or "ok"
            device.error = f"ioctl failed ({error.strerror}); OpenCV probe: {probe}"
        finally:
            os.close(fd)
        device.links = links.get(os.path.realpath(path), [])
        devices.append(device)
    return devices


def probe_with_opencv(path: str) -> VideoDevice:
    """Open the device with OpenCV asking for MJPG 640×480×30 and report what it negotiated."""
    from capture.sources import V4L2Source

    device = VideoDevice(path, probe="opencv")
    source = V4L2Source(path)
    try:
        source.open()
        got = source.negotiated
        assert got is not None  # open() returned, so it negotiated
        size = FrameSize(got.width, got.height, (got.fps,))
        device.formats.append(PixelFormat(got.fourcc, "negotiated by OpenCV", (size,)))
    except Exception as error:
        device.capture = False
        device.error = str(error)
    finally:
        source.close()
    return device
