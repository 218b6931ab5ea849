"""`momloc cameras` (placeholder until its issue lands; the owner replaces this whole file)."""

from __future__ import annotations

import argparse

from models.errors import MomlocError


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("cameras", help="(not yet available)")
    parser.add_argument("rest", nargs=argparse.REMAINDER)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    raise MomlocError("'momloc cameras' is not available yet")
