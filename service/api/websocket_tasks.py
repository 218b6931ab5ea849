"""A WebSocket route's two halves: a sender and a receiver that notices the client leave.

Both WebSocket routes (``/v1/stream``, ``/v1/events``) send from a subscription while another task
reads, so that a closed client is noticed even when nothing is being sent. Whichever ends first
ends both; their errors are the client's going away (nothing to report).
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Coroutine
from typing import Any

from fastapi import WebSocket, WebSocketDisconnect


async def until_disconnect(websocket: WebSocket) -> None:
    """Read (and drop) client messages until the client disconnects."""
    while (await websocket.receive())["type"] != "websocket.disconnect":
        pass


async def run_until_either(sender: Coroutine[Any, Any, None], websocket: WebSocket) -> None:
    """Run ``sender`` beside :func:`until_disconnect`; when one ends, cancel the other."""
    tasks = [asyncio.create_task(sender), asyncio.create_task(until_disconnect(websocket))]
    try:
        await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
    finally:
        for task in tasks:
            task.cancel()
        for task in tasks:
            with contextlib.suppress(asyncio.CancelledError, WebSocketDisconnect, Exception):
                await task
