"""What starts and stops with the app: the hub's event loop, the pipeline, the model watcher, the
outputs (MQTT, OSC, zone events) and, on the way out, the set-up flow's parts.

Order: the outputs start after the pipeline (MQTT's first health message has something to say)
and stop before it (MQTT publishes ``offline`` while positions still flow). They are entered
here, not given to ``APIRouter(lifespan=...)``: FastAPI releases before 0.112 (our floor is
0.110) never run a router's lifespan, so MQTT would silently never connect there (found by
``make test-floors``).
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Callable
from contextlib import AbstractAsyncContextManager, asynccontextmanager

from fastapi import FastAPI

from service.api.state import Daemon
from service.outputs.wiring import Outputs


def daemon_lifespan(
    daemon: Daemon, manage_pipeline: bool
) -> Callable[[FastAPI], AbstractAsyncContextManager[None]]:
    """The app's lifespan; with ``manage_pipeline`` it starts and stops the pipeline too."""

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        daemon.hub.bind(asyncio.get_running_loop())
        if manage_pipeline:
            await asyncio.to_thread(daemon.pipeline.start)
        if daemon.watcher is not None:
            daemon.watcher.start()
        try:
            async with outputs_running(daemon.outputs):
                yield
        finally:
            if daemon.watcher is not None:
                daemon.watcher.stop()
            if daemon.setup is not None:
                await asyncio.to_thread(daemon.setup.stop)
            if daemon.training is not None:
                await asyncio.to_thread(daemon.training.cancel)  # no orphan child process
            if daemon.verifier is not None:
                await asyncio.to_thread(daemon.verifier.stop)
            if manage_pipeline:
                await asyncio.to_thread(daemon.pipeline.stop)
            daemon.hub.bind(None)

    return lifespan


@asynccontextmanager
async def outputs_running(outputs: Outputs | None) -> AsyncIterator[None]:
    """Start the publishers (in their settings' order) and zone events with the app; stop them
    in the reverse order. ``start`` may resolve or connect: off the event loop."""
    if outputs is None:
        yield
        return
    outputs.zones.events.bind(asyncio.get_running_loop())
    publishers = list(outputs.publishers.values())
    for publisher in publishers:
        await asyncio.to_thread(publisher.start)
    try:
        yield
    finally:
        for publisher in reversed(publishers):
            await asyncio.to_thread(publisher.stop)
        outputs.zones.events.bind(None)
