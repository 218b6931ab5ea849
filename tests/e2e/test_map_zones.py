"""Zones on the live map (real headless Chromium): outlines, fill, occupancy list."""

from __future__ import annotations

import pytest

from tests.e2e.server import running_server
from tests.e2e.test_map_page import browser, wait_until  # noqa: F401 (fixture)

pytestmark = [pytest.mark.browser, pytest.mark.timeout(600)]

PIXEL = """
const [cx, cy] = window.momloc.toCanvas(arguments[0], arguments[1]);
const d = document.getElementById('map').getContext('2d').getImageData(cx, cy, 1, 1).data;
return [d[0], d[1], d[2]];
"""


def test_demo_zones_are_drawn_with_their_occupancy(browser):  # noqa: F811
    with running_server() as srv:
        srv.wait_for_seq(10)
        browser.get(f"{srv.http}/")
        names = wait_until(
            lambda: browser.execute_script("return window.momloc.zones.map(z => z.name)"),
            what="zones from /v1/config",
        )
        assert names == ["kitchen", "lounge"]
        wait_until(lambda: browser.execute_script("return window.momloc.toCanvas !== null"))

        def listed() -> dict:
            return (
                browser.execute_script(  # one atomic read: the list is re-rendered twice a second
                    "return Object.fromEntries([...document.querySelectorAll('#zones li')]"
                    ".map(li => [li.dataset.zone, Number(li.dataset.count)]))"
                )
            )

        def api() -> dict:
            return {z["name"]: z["count"] for z in srv.get("/v1/zones").json()["zones"]}

        wait_until(lambda: listed() and listed() == api(), what="zone list matching /v1/zones")
        # the concave lounge: filled inside its L, floor colour in its notch
        inside = browser.execute_script(PIXEL, 6.5, 6.3)
        notch = browser.execute_script(PIXEL, 6.3, 8.6)
        floor = browser.execute_script(PIXEL, 4.6, 4.6)  # between the zones
        assert notch == floor, (notch, floor)
        assert inside != floor and inside[2] > floor[2], (inside, floor)
