"""`momloc cameras`: list the V4L2 cameras present and the formats they offer.

What a user needs before writing the camera settings: which ``/dev/video*`` are real capture
devices (UVC webcams also create metadata nodes), their stable ``/dev/v4l/by-id`` names (indices
change when cameras are replugged), and whether they offer MJPG 640×480 at 30 fps, the mode
momloc asks for.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # loaded when the command runs: `momloc --help` stays fast
    from capture.v4l2 import VideoDevice

WANTED = ("MJPG", 640, 480, 30.0)


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "cameras",
        help="list V4L2 cameras and their formats",
        description="List /dev/video* capture devices, their stable names and formats.",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON array")
    parser.add_argument("--dev-root", default="/dev", help=argparse.SUPPRESS)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from capture.v4l2 import list_devices

    devices = list_devices(args.dev_root)
    if args.json:
        print(json.dumps([asdict(device) for device in devices], indent=2))
        return 0
    if not devices:
        print(
            f"No V4L2 cameras found: {args.dev_root}/video* does not exist.\n"
            "Plug in a USB webcam (in Docker, pass it with --device /dev/video0), or try the "
            "synthetic scene with `momloc demo`."
        )
        return 0
    for device in devices:
        print("\n".join(describe(device)))
    captures = [d for d in devices if d.capture]
    print(f"\n{len(captures)} capture device(s); momloc uses MJPG 640x480 at 30 fps.")
    return 0


def describe(device: VideoDevice) -> list[str]:
    title = device.card or "(unknown camera)"
    extra = ", ".join(x for x in (device.driver, device.bus) if x)
    lines = [f"{device.path}  {title}" + (f" ({extra})" if extra else "")]
    if not device.capture:
        lines.append("    not a video capture node (metadata or output): skip it")
    for link in device.links:
        lines.append(f"    stable name: {link}")
    for fmt in device.formats:
        sizes = ", ".join(
            f"{s.width}x{s.height}"
            + (" (max, stepwise)" if s.stepwise else "")
            + (f" @ {'/'.join(f'{r:g}' for r in s.fps)} fps" if s.fps else "")
            for s in fmt.sizes
        )
        lines.append(f"    {fmt.fourcc:<4}  {fmt.description}: {sizes or 'no sizes listed'}")
    if device.capture and device.formats:
        ok = any(
            fmt.fourcc == WANTED[0]
            and any((s.width, s.height) == WANTED[1:3] and WANTED[3] in s.fps for s in fmt.sizes)
            for fmt in device.formats
        )
        lines.append("    MJPG 640x480 @ 30 fps: " + ("yes" if ok else "NOT offered"))
    if device.error:
        lines.append(f"    note: {device.error}")
    return lines
