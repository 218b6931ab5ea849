"""`momloc demo`: the daemon on the embedded synthetic scene, no cameras needed."""

from __future__ import annotations

import argparse


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "demo",
        help="run the daemon on the embedded synthetic scene (no cameras needed)",
        description=(
            "Start the full daemon (pipeline, API, live map) on a simulated room with walking "
            "people and the shipped demo model. Open the printed map URL in a browser."
        ),
    )
    parser.add_argument("--host", default=None, help="bind address (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=None, help="TCP port (default 8765)")
    parser.add_argument(
        "--detections",
        choices=("simulated", "rendered"),
        default=None,
        help="rendered: drawn frames through the real detector (default); "
        "simulated: the simulator's noisy boxes (no drawing, no detector: for small machines)",
    )
    parser.add_argument("--people", type=int, default=None, help="walking people (default 3)")
    parser.add_argument("--seed", type=int, default=None, help="scene seed")
    parser.add_argument(
        "--profile",
        default=None,
        metavar="NAME",
        help="simulated detector profile: nanodet (default), ssdlite, ideal, or a JSON path",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from service.commands.serve import serve_settings
    from service.demo import demo_settings

    settings = demo_settings(
        host=args.host,
        port=args.port,
        detections=args.detections,
        people=args.people,
        seed=args.seed,
        profile=args.profile,
    )
    mode = settings.synthetic.detections
    return serve_settings(settings, banner=f"demo scene, {mode} detections")
