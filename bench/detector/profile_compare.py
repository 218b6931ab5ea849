"""Old against new: the same accuracy table under two detector profiles, side by side.

``python -m bench.detector.profile_compare OLD.md NEW.md --out FILE.md`` reads two results files
written by ``bench.serving.stream_accuracy`` (the same scenes and variants, each under its own
profile) and writes one table whose every metric has an *old* and a *new* column, labelled with the
profile each file names. Why: when a profile is rebuilt from better evidence (issue 23 dropped
NanoDet's MultiviewX rows), every figure that rested on the old one moves, and a reader needs
both to judge the change, not a silently replaced number.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from bench.report import command_line, markdown_table

KEYS = ("precision %", "recall %", "MOTA % (1 m)", "id sw.", "mean / median m", "Acc@0.3 %")


def rows(path: Path) -> tuple[str, dict[tuple[str, str, str], dict[str, str]]]:
    """(profile named in the file and the run's date, {(scene, people, variant): {column:
    cell}}) of the first table of a ``bench.serving.stream_accuracy`` result."""
    text = path.read_text()
    match = re.search(r"Detector profile: ([^ .]+)", text)
    date = re.search(r" on (\d{4}-\d\d-\d\d \d\d:\d\d UTC)", text)
    profile = (match.group(1) if match else path.name) + (f", run {date.group(1)}" if date else "")
    lines = [line for line in text.splitlines() if line.startswith("|")]
    header = [c.strip() for c in lines[0].strip("|").split("|")]
    out = {}
    for line in lines[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) != len(header) or cells[0] == header[0]:
            break
        record = dict(zip(header, cells, strict=True))
        out[(record["scene"], record["people"], record["variant"])] = record
    return profile, out


def compare(old: Path, new: Path) -> str:
    """The side-by-side table of the rows both files hold."""
    old_name, old_rows = rows(old)
    new_name, new_rows = rows(new)
    table = []
    for key, fresh in new_rows.items():
        if key in old_rows:
            table.append([*key, *(f"{old_rows[key][k]} → {fresh[k]}" for k in KEYS)])
    header = ("scene", "people", "variant", *KEYS)
    return (
        f"Each cell: old profile `{old_name}` ({old}) → rebuilt `{new_name}` ({new}), same "
        "scenes, seeds and frames; the rest of the code may have changed between the two runs "
        "too (the old run is older).\n\n" + markdown_table(header, table) + "\n"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old", type=Path)
    parser.add_argument("new", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--title", default="Streamed accuracy: old and rebuilt detector profile")
    args = parser.parse_args(argv)
    command = command_line("bench.detector.profile_compare", argv)
    args.out.write_text(f"# {args.title}\n\nWritten by `{command}`. {compare(args.old, args.new)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
