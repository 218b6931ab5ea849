"""The ``momloc`` command line.

Each subcommand lives in ``service/commands/<name>.py`` and exposes ``register(subparsers)``, which
adds its parser and sets ``func``. Modules are imported lazily only for ``--help`` listing cost, so
``momloc demo`` never imports torch.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys

from common.errors import MomlocError, shorten
from service.stop_signals import Stopped, handle_stop_signals

COMMANDS = (
    "demo",
    "serve",
    "cameras",
    "detect",
    "simulate",
    "collect",
    "train",
    "eval",
    "record",
    "track",
    "import_mot",
    "bridge",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="momloc",
        description="Mean of Means human localization: calibration-free, tag-free, cheap webcams.",
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"service.commands.{name}").register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    with handle_stop_signals():  # Ctrl-C and SIGTERM, however the command was started
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    try:
        return int(args.func(args) or 0)
    except MomlocError as error:
        lines = str(error).splitlines() or [""]  # settings errors: one line per field
        for line in lines:
            print(f"momloc {args.command}: error: {shorten(line, 500)}", file=sys.stderr)
        return 2
    except OSError as error:  # a path the user gave that the OS refuses (too long, no access)
        where = f"{shorten(error.filename, 160)}: " if error.filename else ""
        print(f"momloc {args.command}: error: {where}{error.strerror}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as stop:  # the command cleaned up: say so, exit as shells expect
        signum = stop.signum if isinstance(stop, Stopped) else signal.SIGINT
        name = signal.Signals(signum).name
        print(f"momloc {args.command}: interrupted ({name}), stopped", file=sys.stderr)
        return 128 + signum


if __name__ == "__main__":
    sys.exit(main())
