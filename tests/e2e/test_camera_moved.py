"""A camera bumped while the real daemon runs: /v1/health and the map page name it."""

from __future__ import annotations

import functools
import time

import pytest

import service.detection.simulated
import service.pipeline.listeners
from models.simulate import Perturbation
from tests.e2e.server import running_server

pytestmark = pytest.mark.timeout(120)

BUMP_S = 10.0  # scene seconds after start; the references are ready after ~2.5 s (see below),
# ~5 s on a busy machine


def _bumped_scene(monkeypatch: pytest.MonkeyPatch, camera: int) -> None:
    """Make the demo's scene bump ``camera`` 20 px sideways ``BUMP_S`` into the run, with image
    references taken 0.5 s apart (default 1 s) so they are complete well before the bump."""
    original = service.detection.simulated.make_scene

    def make_scene(preset, **kw):
        fps = kw.get("fps") or 30.0
        bump = Perturbation(camera=camera, start_frame=int(BUMP_S * fps), dx=20.0)
        return original(preset, **kw, perturbations=[bump])

    monkeypatch.setattr(service.detection.simulated, "make_scene", make_scene)
    monkeypatch.setattr(
        service.pipeline.listeners,
        "CameraShiftMonitor",
        functools.partial(service.pipeline.listeners.CameraShiftMonitor, reference_spacing_s=0.5),
    )


def _references_ready_before_bump(srv) -> None:
    """Wait for both cameras' image references. A machine so starved that they were only taken
    after the bump has, rightly, the bumped view as reference and nothing to flag: skip then.
    The deadline is a liveness bound for a loaded machine (a 30 s one failed under load)."""
    deadline = time.time() + 150
    while not all(
        c["alignment"]["reference"] == "ready" for c in srv.get("/v1/health").json()["cameras"]
    ):
        assert time.time() < deadline, "image references never became ready"
        time.sleep(0.1)
    scene_s = time.time() - srv.daemon.pipeline.rig.t0
    if scene_s >= BUMP_S:
        pytest.skip(f"image references ready only {scene_s:.1f} s in, after the bump at {BUMP_S} s")


def _wait_moved(srv, timeout: float = 120.0) -> dict:
    deadline = time.time() + timeout
    health = srv.get("/v1/health").json()
    while not any(c["alignment"]["moved"] for c in health["cameras"]):
        assert time.time() < deadline, health["cameras"]
        time.sleep(0.25)
        health = srv.get("/v1/health").json()
    return health


def test_health_reports_the_moved_camera(monkeypatch: pytest.MonkeyPatch) -> None:
    _bumped_scene(monkeypatch, camera=1)
    with running_server(token="t0k") as srv:
        _references_ready_before_bump(srv)
        before = srv.get("/v1/health").json()
        assert not any(c["alignment"]["moved"] for c in before["cameras"])
        health = _wait_moved(srv)
        cams = health["cameras"]
        assert cams[1]["alignment"]["moved"] and not cams[0]["alignment"]["moved"]
        assert cams[1]["alignment"]["shift_px"] > 15 and cams[0]["alignment"]["shift_px"] < 2
        assert "camera 1" in cams[1]["alignment"]["message"]
        assert "momloc collect" in cams[1]["alignment"]["message"]
        assert health["status"] == "degraded"


@pytest.mark.browser
def test_map_page_shows_the_moved_banner(monkeypatch: pytest.MonkeyPatch) -> None:
    from tests.e2e.test_map_page import CHROMEDRIVER, CHROMIUM, FLAGS, ensure_chromium, wait_until

    ensure_chromium()
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    _bumped_scene(monkeypatch, camera=0)
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in FLAGS:
        options.add_argument(flag)
    with running_server() as srv:
        _references_ready_before_bump(srv)
        driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
        try:
            driver.get(srv.http + "/")
            banner = driver.find_element("id", "moved-banner")
            assert not banner.is_displayed()
            wait_until(banner.is_displayed, timeout=40, what="camera-moved banner")
            assert "Camera 0" in banner.text and "momloc train" in banner.text
            assert driver.execute_script("return window.momloc.moved") == [0]
            figures = driver.find_elements("css selector", "#cameras figure.moved")
            assert [f.get_attribute("data-k") for f in figures] == ["0"]
            assert "MOVED" in figures[0].text
        finally:
            driver.quit()
