"""The whole first run in real headless Chromium: the map says "no model yet" and links to
/setup; there the previews show what each camera sees, Start records the marks (the synthetic
person follows the instructions), Train runs in the background and the model is hot-loaded,
Check shows the error summary, and the map shows the person. Screenshots of each step are saved
under the test's tmp directory (``screenshots/``)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from models.data.dataset import MomDataset
from service.api.server import serve_in_thread
from service.daemon import build_daemon
from tests.e2e.test_map_page import browser, people, wait_until  # noqa: F401 (fixture)
from tests.e2e.test_privacy import images_in
from tests.e2e.test_setup_flow import setup_settings

pytestmark = [pytest.mark.browser, pytest.mark.timeout(600)]


def text(driver, element_id: str) -> str:
    return driver.find_element("id", element_id).text


def shoot(driver, path: Path, element_id: str | None = None) -> None:
    """Screenshot, with ``element_id`` scrolled into view first."""
    if element_id is not None:
        driver.execute_script(f"document.getElementById('{element_id}').scrollIntoView()")
    driver.save_screenshot(str(path))


def fill(driver, element_id: str, value: str) -> None:
    field = driver.find_element("id", element_id)
    field.clear()
    field.send_keys(value)


def record_marks(driver, grid: str, seconds: int) -> None:
    """Fill the form for a grid of marks in the 10 m room and press Start."""
    fill(driver, "grid", grid)
    fill(driver, "room", "10x10")
    fill(driver, "seconds", str(seconds))
    fill(driver, "move-seconds", "5")
    fill(driver, "countdown-seconds", "1")
    driver.find_element("id", "start").click()


def test_first_run_in_the_browser(browser, tmp_path: Path) -> None:  # noqa: F811
    shots = tmp_path / "screenshots"
    shots.mkdir()
    daemon = build_daemon(setup_settings(tmp_path))
    assert daemon.training is not None  # build_daemon always makes one
    server = serve_in_thread(daemon)
    base = f"http://127.0.0.1:{server.port}"
    driver = browser
    try:
        # the live map: no model yet, and a link to /setup
        driver.get(base + "/")
        wait_until(lambda: driver.find_element("id", "setup-banner").is_displayed(), 30, "banner")
        assert "no model yet" in text(driver, "setup-banner").lower()
        driver.save_screenshot(str(shots / "01-map-no-model.png"))
        driver.find_element("id", "setup-link").click()
        wait_until(lambda: driver.current_url.endswith("/setup"), 10, "on /setup")
        wait_until(lambda: "No model yet" in text(driver, "intro"), 30, "intro")

        # see: both previews drawn, each camera sees the one person
        wait_until(
            lambda: (
                driver.execute_script(
                    "return [...document.querySelectorAll('#previews img')]"
                    ".filter(i => i.naturalWidth > 0).length"
                )
                == 2
            ),
            60,
            "previews",
        )
        wait_until(lambda: "sees 1 person" in text(driver, "previews"), 30, "one person seen")
        driver.save_screenshot(str(shots / "02-setup-previews.png"))

        # record 2 x 2 marks
        record_marks(driver, "2x2", 4)
        wait_until(lambda: "go to mark" in text(driver, "instruction"), 20, "instruction")
        wait_until(
            lambda: driver.execute_script(
                "const s = window.momlocSetup.status;"
                "return s && s.marks.some(m => m.state === 'done')"
            ),
            60,
            "a mark recorded",
        )
        driver.save_screenshot(str(shots / "03-recording.png"))
        wait_until(lambda: driver.find_element("id", "train-panel").is_displayed(), 120, "recorded")
        assert text(driver, "instruction") == "all marks recorded"
        rows = driver.execute_script(  # one read: the table is redrawn with every status
            "return [...document.querySelectorAll('#quality tbody tr')].map(r => r.innerText)"
        )
        assert [r.split()[0] for r in rows] == ["A1", "A2", "B2", "B1"], rows
        assert all("record this mark again" in r for r in rows)
        shoot(driver, shots / "04-recorded-quality.png", "quality-panel")

        # train: progress on the page, then the model is loaded
        fill(driver, "epochs", "12")
        driver.find_element("id", "train").click()
        wait_until(lambda: "epoch" in text(driver, "train-state"), 180, "training progress")
        shoot(driver, shots / "05-training.png", "train-panel")
        wait_until(lambda: text(driver, "train-state").startswith("trained"), 300, "trained")
        assert "model loaded from" in text(driver, "train-state")
        assert daemon.pipeline.runtime is not None
        wait_until(lambda: "Model loaded from" in text(driver, "intro"), 10, "intro after train")

        # check two marks
        wait_until(lambda: driver.find_element("id", "verify-panel").is_displayed(), 10, "check")
        fill(driver, "verify-marks", "A2 7.5 2.5\nM 5 5")
        fill(driver, "verify-seconds", "3")
        fill(driver, "move-seconds", "4")
        driver.find_element("id", "verify").click()
        try:
            summary = wait_until(
                lambda: re.fullmatch(
                    r"median \d+\.\d\d m over 2 marks", text(driver, "verify-summary")
                ),
                90,
                "verification summary",
            )
        except AssertionError as error:  # say what the page showed (a mark nobody was seen on?)
            shown = text(driver, "verify-summary")
            raise AssertionError(f"{error}; the page shows {shown!r}") from None
        assert float(summary.group(0).split()[1]) < 1.0
        shoot(driver, shots / "06-checked.png", "verify-panel")

        # positions on the map, no "no model" banner any more
        driver.find_element("id", "to-map").click()
        wait_until(lambda: len(people(driver)) == 1, 30, "a person on the map")
        wait_until(lambda: not driver.find_element("id", "setup-banner").is_displayed(), 10, "x")
        driver.save_screenshot(str(shots / "07-map-positions.png"))
        assert all(shot.stat().st_size > 10_000 for shot in shots.iterdir())
    finally:
        server.stop()
        daemon.training.cancel()


def test_setup_page_in_privacy_mode_records_from_boxes(browser, tmp_path, monkeypatch):  # noqa: F811
    """``MOMLOC_PRIVACY=positions_only``: the set-up page's previews are boxes on an empty
    background (no image loaded), it still tells who each camera sees, and recording the marks
    works (it records detections, never images: no image file or bytes in the data folder)."""
    monkeypatch.setenv("MOMLOC_PRIVACY", "positions_only")
    daemon = build_daemon(setup_settings(tmp_path))
    assert daemon.training is not None  # build_daemon always makes one
    server = serve_in_thread(daemon)
    driver = browser
    try:
        driver.get(f"http://127.0.0.1:{server.port}/setup")
        wait_until(
            lambda: (
                driver.execute_script(
                    "return [...document.querySelectorAll('#previews canvas.preview')]"
                    ".filter(c => Number(c.dataset.boxes) === 1).length"
                )
                == 2
            ),
            60,
            "one box drawn in each preview",
        )
        wait_until(lambda: text(driver, "previews").count("sees 1 person") == 2, 30, "seen")
        assert driver.execute_script("return document.querySelectorAll('img').length") == 0
        driver.save_screenshot(str(tmp_path / "setup-privacy.png"))
        record_marks(driver, "1x2", 3)
        wait_until(lambda: driver.find_element("id", "train-panel").is_displayed(), 120, "recorded")
        rows = driver.execute_script(
            "return [...document.querySelectorAll('#quality tbody tr')].map(r => r.innerText)"
        )
        assert [r.split()[0] for r in rows] == ["A1", "A2"], rows
        fetched = driver.execute_script(
            "return performance.getEntriesByType('resource').map(e => e.name)"
        )
        assert not [url for url in fetched if "snapshot.jpg" in url], fetched
        assert MomDataset.load(tmp_path / "data" / "setup.npz").n > 0  # detections recorded
        files = [p for p in (tmp_path / "data").rglob("*") if p.is_file()]
        assert {p.suffix for p in files} == {".npz", ".json"}, files  # datasets and marks
        assert not [p for p in files if images_in(p.read_bytes())], files
    finally:
        server.stop()
        daemon.training.cancel()
