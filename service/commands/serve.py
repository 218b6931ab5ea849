"""`momloc serve`: the daemon on the cameras of a settings file."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # command modules import what they run inside the command (fast --help)
    from service.settings import Settings


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "serve",
        help="run the daemon on real cameras",
        description=(
            "Run the localization daemon. Settings come from --config (YAML) and MOMLOC_* "
            "environment variables (MOMLOC_PORT=9000, MOMLOC_DETECTOR__SCORE_THRESHOLD=0.5); "
            "--host/--port win over both."
        ),
    )
    parser.add_argument("--config", type=Path, default=None, help="settings file (YAML)")
    parser.add_argument("--host", default=None, help="bind address (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=None, help="TCP port (default 8765)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from service.settings import load_settings

    settings = load_settings(args.config, host=args.host, port=args.port)
    return serve_settings(settings, banner=f"{len(settings.cameras)} camera(s)")


def serve_settings(settings: Settings, banner: str) -> int:
    """Build the daemon, print where to find it, serve until Ctrl-C."""
    from service.api.server import run_server
    from service.daemon import build_daemon
    from service.settings import POSITIONS_ONLY

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    daemon = build_daemon(settings)
    host = settings.host

    def announce(port: int) -> None:
        shown = "127.0.0.1" if host in ("0.0.0.0", "::") else host
        shown = f"[{shown}]" if ":" in shown else shown
        query = "?token=…" if settings.token else ""
        model = daemon.pipeline.model_dir
        print(f"momloc: {banner}; model {model or 'none (set-up mode)'}", flush=True)
        if daemon.setup_mode:
            print(f"  set up:    http://{shown}:{port}/setup{query}  <- open this first: "
                  "no model yet, record floor marks and train there", flush=True)  # fmt: skip
        print(f"  live map:  http://{shown}:{port}/{query}", flush=True)
        print(f"  stream:    ws://{shown}:{port}/v1/stream{query}", flush=True)
        print(f"  API docs:  http://{shown}:{port}/docs", flush=True)
        if settings.privacy == POSITIONS_ONLY:
            print("  privacy:   positions only, no camera image is served or stored", flush=True)
        print("  Ctrl-C to stop", file=sys.stderr, flush=True)

    run_server(daemon, host, settings.port, on_ready=announce)
    return 0
