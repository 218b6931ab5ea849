"""`momloc train` (placeholder until its issue lands; the owner replaces this whole file)."""

from __future__ import annotations

import argparse

from models.errors import MomlocError


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("train", help="(not yet available)")
    parser.add_argument("rest", nargs=argparse.REMAINDER)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    raise MomlocError("'momloc train' is not available yet")
