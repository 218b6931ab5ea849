"""The browser client (examples/web) in real headless Chromium against the live demo daemon.

The page is mounted on the daemon's own app (``tests.e2e.server``'s ``static``), so it is served
from the daemon's origin exactly as the Origin checks require: a page on another port would be
refused. A tap on the hub records every published snapshot to check what the page parsed.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from tests.e2e.client_checks import Tap
from tests.e2e.mqtt_broker import free_port
from tests.e2e.server import running_server
from tests.e2e.test_map_page import CHROMEDRIVER, CHROMIUM, FLAGS, ensure_chromium, wait_until

pytestmark = [pytest.mark.browser, pytest.mark.timeout(600)]

WEB = Path(__file__).resolve().parents[2] / "examples" / "web"
STATIC = {"/examples/web": WEB}
TOKEN = "web-token"


@pytest.fixture(scope="module")
def chromium():
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


def page_state(driver) -> dict[str, Any]:
    """Markers drawn, the client's raw last snapshot and its people, read at one instant."""
    return driver.execute_script(
        "const d = window.momlocDemo; if (!d) return null;"
        "return {connected: d.client.connected, rejected: d.client.tokenRejected,"
        " attempts: d.client.attempts, draws: d.draws, markers: d.markers,"
        " last: d.client.lastSnapshot, people: Object.fromEntries(d.client.people()),"
        " status: document.getElementById('status').textContent};"
    )


INTERPOLATION = """
const done = arguments[arguments.length - 1];
import('/examples/web/momloc-client.js').then(({ MomlocClient }) => {
  const c = new MomlocClient({ url: 'ws://127.0.0.1:1/v1/stream', delay: 0.1,
                               maxExtrapolate: 0.25 });
  const person = (id, x, y, vx) => ({ id, x, y, vx, vy: 0, confidence: 0.5, cameras: [0] });
  // daemon clock 1000.0 s, local clock 20.0 s; the second snapshot arrives 30 ms late
  c.ingest({ v: 1, seq: 1, t: 1000.0, people: [person(1, 0, 0, 1), person(2, 5, 5, 0)] }, 20.0);
  c.ingest({ v: 1, seq: 2, t: 1000.1, people: [person(1, 1, 2, 1), person(2, 5, 5, 0)] }, 20.13);
  const at = (now) => Object.fromEntries(c.people(now));
  const out = { render: c.renderTime(20.15), mid: at(20.15), ahead: at(20.5) };
  c.ingest({ v: 1, seq: 3, t: 1000.2, people: [person(2, 5, 5, 0)] }, 20.2);  // id 1 left
  out.beforeGone = Object.keys(at(20.25));
  out.afterGone = Object.keys(at(20.31));
  done(out);
}).catch((e) => done({ error: String(e) }));
"""


def test_client_interpolates_between_snapshots_and_drops_who_left(chromium):
    with running_server(static=STATIC) as srv:
        chromium.get(f"{srv.http}/examples/web/index.html")
        out = chromium.execute_async_script(INTERPOLATION)
    assert "error" not in out, out
    # offset = 20.0 - 1000.0 (the least-delayed snapshot), crept 1 % towards the late one's
    # (+0.03 s); render time = now - offset - delay
    offset = (20.0 - 1000.0) + 0.01 * 0.03
    render = 20.15 - offset - 0.1
    assert out["render"] == pytest.approx(render, abs=1e-9)
    u = (render - 1000.0) / 0.1
    assert (out["mid"]["1"]["x"], out["mid"]["1"]["y"]) == pytest.approx((u, 2 * u), abs=1e-9)
    assert (out["mid"]["2"]["x"], out["mid"]["2"]["y"]) == (5, 5)
    # past the newest sample: on with the velocity, at most maxExtrapolate seconds
    assert out["ahead"]["1"]["x"] == pytest.approx(1 + 0.25, abs=1e-9)
    assert out["ahead"]["1"]["y"] == pytest.approx(2, abs=1e-9)
    assert sorted(out["beforeGone"]) == ["1", "2"] and out["afterGone"] == ["2"]


def test_demo_page_markers_follow_the_daemon_and_reconnect(chromium):
    port = free_port()
    with running_server(token=TOKEN, port=port, static=STATIC) as srv:
        srv.wait_for_seq(10)
        tap = Tap()
        srv.daemon.hub.add_publisher(tap)
        chromium.get(f"{srv.http}/examples/web/index.html?token={TOKEN}")
        first = wait_until(
            lambda: (s := page_state(chromium)) and s["connected"] and len(s["markers"]) >= 2 and s,
            what="markers on the page",
        )
        time.sleep(1.5)
        second = page_state(chromium)
        common = set(first["markers"]) & set(second["markers"])
        assert common, (first, second)
        moved = max(
            abs(first["markers"][i]["x"] - second["markers"][i]["x"])
            + abs(first["markers"][i]["y"] - second["markers"][i]["y"])
            for i in common
        )
        assert moved > 0.05 and second["draws"] > first["draws"]
        # the page parsed exactly what the daemon published, and draws it close to it
        last = second["last"]
        assert last == tap.by_seq[last["seq"]].as_dict()
        latest = {str(p["id"]): p for p in last["people"]}
        for i, p in second["people"].items():
            if i in latest:
                assert abs(p["x"] - latest[i]["x"]) + abs(p["y"] - latest[i]["y"]) < 1.0
        assert "connected" in second["status"]
    # daemon stopped: the page notices, then reconnects when it is back on the same port
    wait_until(lambda: not page_state(chromium)["connected"], what="the page to notice")
    with running_server(token=TOKEN, port=port, static=STATIC) as again:
        again.wait_for_seq(10)
        tap = Tap()
        again.daemon.hub.add_publisher(tap)
        state = wait_until(
            lambda: (
                (s := page_state(chromium))
                and s["connected"]
                and s["last"]["seq"] in tap.by_seq
                and len(s["markers"]) >= 2
                and s
            ),
            timeout=60,
            what="the page to reconnect and draw the restarted daemon's people",
        )
        assert state["attempts"] >= 2 and not state["rejected"]
        assert state["last"] == tap.by_seq[state["last"]["seq"]].as_dict()


def test_demo_page_reports_a_wrong_token_and_stops_retrying(chromium):
    with running_server(token=TOKEN, static=STATIC) as srv:
        srv.wait_for_seq(5)
        chromium.get(f"{srv.http}/examples/web/index.html?token=wrong")
        # the page sets its rejected flag and its status line in two steps: wait for both
        state = wait_until(
            lambda: (
                (s := page_state(chromium))
                and s["rejected"]
                and "token rejected" in s["status"]
                and s
            ),
            what="4401 and the status line",
        )
        assert "token rejected" in state["status"]
        time.sleep(3.0)  # several back-off periods: a retrying client would have tried again
        later = page_state(chromium)
        assert later["attempts"] == state["attempts"] == 1
        assert later["markers"] == {} and later["last"] is None
