"""Take the README's and the docs' picture of the live map: docs/img/live-map.png.

Runs ``momloc demo`` (the real daemon on the drawn demo scene, real detector) on a free loopback
port, opens its map page in headless Chromium (Debian's ``chromium`` + ``chromium-driver``, the
ones the map-page e2e test uses, driven by Selenium from the dev extra), waits until the map has
drawn people for a while, and stores the page as a small PNG (scaled to ``--width``, palette
compressed). Re-run after changing the map page::

    .venv/bin/python tools/screenshot_map.py            # writes docs/img/live-map.png

A picture of the real page, rather than a drawing of it, so the docs show what ``make demo``
shows.
"""

from __future__ import annotations

import argparse
import json
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

from PIL import Image

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "docs" / "img" / "live-map.png"
CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
WINDOW = (1280, 860)


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def wait_for_people(url: str, timeout_s: float) -> None:
    """Until the daemon serves a snapshot with people (the detector and tracker are warm)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(f"{url}/v1/positions", timeout=2) as answer:
                if json.load(answer).get("people"):
                    return
        except OSError:
            pass
        time.sleep(0.5)
    raise SystemExit(f"screenshot_map: no people served at {url} within {timeout_s:.0f} s")


def screenshot(url: str, out: Path, settle_s: float) -> None:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars"):
        options.add_argument(flag)
    options.add_argument(f"--window-size={WINDOW[0]},{WINDOW[1]}")
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    try:
        driver.get(f"{url}/")
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if driver.execute_script("return window.momloc && window.momloc.people"):
                break
            time.sleep(0.2)
        time.sleep(settle_s)  # a few seconds of walking: the trails show on the map
        driver.save_screenshot(str(out))
    finally:
        driver.quit()


def shrink(path: Path, width: int) -> None:
    """Scale to ``width`` and store as a 64-colour palette PNG: the map is flat colours."""
    image = Image.open(path).convert("RGB")
    height = round(image.height * width / image.width)
    image = image.resize((width, height), Image.Resampling.LANCZOS)
    image.quantize(colors=64, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--width", type=int, default=960, help="width of the stored PNG")
    parser.add_argument("--settle-s", type=float, default=15.0, help="seconds to watch first")
    args = parser.parse_args(argv)
    for tool in (CHROMIUM, CHROMEDRIVER):
        if not tool.exists():
            print(f"screenshot_map: {tool} missing (apt-get install chromium chromium-driver)")
            return 2
    port = free_port()
    url = f"http://127.0.0.1:{port}"
    momloc = Path(sys.executable).parent / "momloc"
    daemon = subprocess.Popen(
        [str(momloc), "demo", "--port", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        wait_for_people(url, timeout_s=120)
        args.out.parent.mkdir(parents=True, exist_ok=True)
        screenshot(url, args.out, args.settle_s)
    finally:
        daemon.terminate()
        daemon.wait(timeout=30)
    shrink(args.out, args.width)
    print(f"wrote {args.out} ({args.out.stat().st_size // 1024} KiB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
