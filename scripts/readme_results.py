#!/usr/bin/env python3
"""Writes the results table of README.md from a bench_accuracy.json.

Usage: scripts/readme_results.py OUT/bench_accuracy.json [README.md]

Replaces what lies between the lines `<!-- results:begin -->` and
`<!-- results:end -->` with the date and a table of every scene in the file
(written by scripts/bench_accuracy.sh). The date is the file's "date" key when
it has one, else its modification time; the core count is its "cores" key,
else 2 (the benchmark machine). The same JSON always gives the same README.
"""
import datetime
import json
import os
import sys

BEGIN, END = "<!-- results:begin -->", "<!-- results:end -->"


def number(value, digits, scale=1.0):
    return "n/a" if value is None else f"{value * scale:.{digits}f}"


def block(path):
    doc = json.load(open(path))
    date = doc.get("date") or datetime.date.fromtimestamp(os.path.getmtime(path)).isoformat()
    lines = [f"Measured by `scripts/bench_accuracy.sh` on {date}, {doc.get('cores', 2)} cores:", "",
             "| scene | tuned on / held out | DSM MAE (m) | median (m) | completeness (%) | run time (s) |",
             "|---|---|---|---|---|---|"]
    for s in doc["scenes"]:
        lines.append(f"| {s['scene']} | {'tuned on' if s.get('tuned_on') else 'held out'} | "
                     f"{number(s.get('mae_m'), 2)} | {number(s.get('median_m'), 2)} | "
                     f"{number(s.get('completeness'), 1, 100)} | {number(s.get('seconds'), 0)} |")
    return "\n".join(lines)


def main(argv):
    if len(argv) not in (2, 3):
        sys.exit(__doc__.strip().splitlines()[2])
    readme = argv[2] if len(argv) == 3 else os.path.join(os.path.dirname(__file__), "..", "README.md")
    text = open(readme).read()
    start, end = text.find(BEGIN), text.find(END)
    if start < 0 or end < start:
        sys.exit(f"readme_results: {readme}: no {BEGIN} ... {END} block")
    new = text[:start + len(BEGIN)] + "\n" + block(argv[1]) + "\n" + text[end:]
    if new != text:
        tmp = readme + ".tmp"
        open(tmp, "w").write(new)
        os.replace(tmp, readme)


if __name__ == "__main__":
    main(sys.argv)
