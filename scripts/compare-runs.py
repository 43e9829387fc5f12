#!/usr/bin/env python3
"""Compare two folders of runs file by file, byte for byte, apart from wall time.

Usage: scripts/compare-runs.py BASE NEW [--only NAME[,NAME...]]

Every file under BASE and NEW (same relative paths) is compared as bytes
after removing what legitimately differs between two runs of the same
settings:
  - the `wall_s` column of CSV files (e.g. metrics.csv);
  - the value of every `"wall_s": <number>` and `"wall_time_s": <number>`
    in JSON files (eval.json, checkpoint.json);
  - the folder itself: occurrences of BASE's and NEW's absolute paths are
    replaced by `<ROOT>` (config.json records the demo file's path).
Nothing else is normalised: a different number anywhere is a difference.

--only restricts the comparison to files with these names (for example
`--only metrics.csv,eval.json`).

Prints one line per file (`same`, `DIFFERS` with the first differing line,
or `only in ...`) and a summary; exits 0 when everything matches, 1
otherwise. Useful to prove that a refactoring kept the numbers: run the same
commands with the old and the new binary into two folders, then compare.
"""

import argparse
import os
import re
import sys

WALL_JSON = re.compile(rb'("wall_s"\s*:\s*|"wall_time_s"\s*:\s*)-?[0-9][0-9.eE+-]*')


def files_under(root):
    out = set()
    for d, _, names in os.walk(root):
        for n in names:
            out.add(os.path.relpath(os.path.join(d, n), root))
    return out


def drop_csv_column(data, column):
    lines = data.split(b"\n")
    header = lines[0].split(b",")
    if column not in header:
        return data
    i = header.index(column)
    kept = []
    for line in lines:
        if not line:
            kept.append(line)
            continue
        cols = line.split(b",")
        if len(cols) > i:
            del cols[i]
        kept.append(b",".join(cols))
    return b"\n".join(kept)


def normalise(path, data, root):
    data = data.replace(os.path.abspath(root).encode(), b"<ROOT>")
    if path.endswith(".csv"):
        data = drop_csv_column(data, b"wall_s")
    elif path.endswith(".json"):
        data = WALL_JSON.sub(rb"\1<wall>", data)
    return data


def first_difference(a, b):
    la, lb = a.split(b"\n"), b.split(b"\n")
    for i, (x, y) in enumerate(zip(la, lb)):
        if x != y:
            return f"line {i + 1}: {x[:120]!r} vs {y[:120]!r}"
    return f"{len(la)} vs {len(lb)} lines"


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("base")
    p.add_argument("new")
    p.add_argument("--only", default="", help="comma-separated file names")
    args = p.parse_args()
    only = {n for n in args.only.split(",") if n}
    base, new = files_under(args.base), files_under(args.new)
    problems = 0
    compared = 0
    for rel in sorted(base | new):
        if only and os.path.basename(rel) not in only:
            continue
        if rel not in new:
            print(f"only in {args.base}: {rel}")
            problems += 1
            continue
        if rel not in base:
            print(f"only in {args.new}: {rel}")
            problems += 1
            continue
        with open(os.path.join(args.base, rel), "rb") as f:
            a = normalise(rel, f.read(), args.base)
        with open(os.path.join(args.new, rel), "rb") as f:
            b = normalise(rel, f.read(), args.new)
        compared += 1
        if a == b:
            print(f"same     {rel}")
        else:
            print(f"DIFFERS  {rel}: {first_difference(a, b)}")
            problems += 1
    print(
        f"{compared} files compared, {problems} difference(s)"
        + (" (wall time excluded)" if problems == 0 else "")
    )
    return 0 if problems == 0 and compared > 0 else 1


if __name__ == "__main__":
    sys.exit(main())
