"""`momloc bridge minecraft`: move one Minecraft entity per tracked person (RCON).

Example::

    momloc bridge minecraft --stream ws://127.0.0.1:8765/v1/stream \\
        --rcon-host 127.0.0.1 --rcon-port 25575 --rcon-password secret --origin 100 64 -20
"""

from __future__ import annotations

import argparse
import os

from common.errors import MomlocError

PASSWORD_ENV = "MOMLOC_RCON_PASSWORD"
TOKEN_ENV = "MOMLOC_TOKEN"


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("bridge", help="forward the position stream to other worlds")
    targets = parser.add_subparsers(dest="target", required=True, metavar="TARGET")
    mc = targets.add_parser(
        "minecraft",
        help="move one entity per person in a Minecraft Java server through RCON",
        description="Subscribe to the daemon's WebSocket stream and move one entity per person id "
        "in a Minecraft Java server (server.properties: enable-rcon=true, rcon.password=...).",
    )
    mc.add_argument(
        "--stream",
        default="ws://127.0.0.1:8765/v1/stream",
        help="WebSocket stream URL (default: %(default)s)",
    )
    mc.add_argument("--token", help=f"API token of the daemon (or ${TOKEN_ENV})")
    mc.add_argument("--rcon-host", default="127.0.0.1", help="default: %(default)s")
    mc.add_argument("--rcon-port", type=int, default=25575, help="default: %(default)s")
    mc.add_argument(
        "--rcon-password", help=f"RCON password (or ${PASSWORD_ENV}, which hides it from ps)"
    )
    mc.add_argument(
        "--origin",
        type=float,
        nargs=3,
        default=(0.0, 64.0, 0.0),
        metavar=("X", "Y", "Z"),
        help="Minecraft block position of the floor origin; Y is the floor height "
        "(default: 0 64 0)",
    )
    mc.add_argument(
        "--scale", type=float, default=1.0, help="blocks per metre (default: %(default)s)"
    )
    mc.add_argument(
        "--entity", default="minecraft:armor_stand", help="entity type (default: %(default)s)"
    )
    mc.add_argument(
        "--nbt",
        help="summon NBT template ($tag, $id, $name are substituted; the default names the "
        "entity 'person N' and tags it momloc and momloc_N)",
    )
    mc.add_argument(
        "--rate", type=float, default=10.0, help="max updates per second (default: %(default)s)"
    )
    mc.add_argument(
        "--max-snapshots", type=int, help="stop after applying this many snapshots (scripting)"
    )
    mc.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import asyncio
    import logging

    from service.outputs.minecraft import DEFAULT_NBT, BridgeConfig, MinecraftBridge, WorldMapping

    password = args.rcon_password or os.environ.get(PASSWORD_ENV)
    if not password:
        raise MomlocError(f"--rcon-password (or ${PASSWORD_ENV}) is required")
    if args.scale <= 0:
        raise MomlocError(f"--scale {args.scale}: must be positive")
    if args.max_snapshots is not None and args.max_snapshots < 1:
        raise MomlocError(f"--max-snapshots {args.max_snapshots}: must be at least 1")
    logging.basicConfig(level=logging.INFO, format="momloc bridge: %(message)s")
    config = BridgeConfig(
        stream_url=args.stream,
        rcon_host=args.rcon_host,
        rcon_port=args.rcon_port,
        rcon_password=password,
        token=args.token or os.environ.get(TOKEN_ENV),
        mapping=WorldMapping(origin=tuple(args.origin), scale=args.scale),
        entity=args.entity,
        nbt=args.nbt or DEFAULT_NBT,
        rate_hz=args.rate,
        max_snapshots=args.max_snapshots,
    )
    bridge = MinecraftBridge(config)
    print(f"momloc bridge: {args.stream} -> RCON {args.rcon_host}:{args.rcon_port}", flush=True)
    applied = asyncio.run(bridge.run())
    print(f"momloc bridge: applied {applied} snapshots", flush=True)
    return 0
