#!/usr/bin/env python3
"""Writes the results table of README.md from bench_accuracy.json files.

Usage: scripts/readme_results.py [--record RECORD.json] OUT/bench_accuracy.json [README.md]

Replaces what lies between the lines `<!-- results:begin -->` and
`<!-- results:end -->` with a table of scenes (written by
scripts/bench_accuracy.sh). Without --record, the table is the file's scenes,
under the file's date. With --record, the file's scenes first replace their
entries in RECORD (the latest full-size measurement of every scene, kept in
the repository, each entry with its date and commit), and the table is the
whole record, each row with the date it was measured: a subset rerun updates
its rows and leaves the others as they were, dated. The date is the file's
"date" key when it has one, else its modification time; the core count is its
"cores" key, else 2 (the benchmark machine). The same inputs always give the
same README.
"""
import datetime
import json
import os
import subprocess
import sys

BEGIN, END = "<!-- results:begin -->", "<!-- results:end -->"
ROW_KEYS = ("scene", "tuned_on", "mae_m", "mae_without_trees_m", "median_m", "completeness", "seconds")


def number(value, digits, scale=1.0):
    return "n/a" if value is None else f"{value * scale:.{digits}f}"


def load(path):
    with open(path) as f:
        return json.load(f)


def run_date(path, doc):
    return doc.get("date") or datetime.date.fromtimestamp(os.path.getmtime(path)).isoformat()


def head_commit():
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None


def row(s, dated):
    cells = [s["scene"], "tuned on" if s.get("tuned_on") else "held out", number(s.get("mae_m"), 2),
             number(s.get("mae_without_trees_m"), 2), number(s.get("median_m"), 2),
             number(s.get("completeness"), 1, 100), number(s.get("seconds"), 0)]
    if dated:
        cells.append(s.get("date", "?") + (f" ({s['commit']})" if s.get("commit") else ""))
    return "| " + " | ".join(cells) + " |"


def block(path):
    doc = load(path)
    lines = [f"Measured by `scripts/bench_accuracy.sh` on {run_date(path, doc)}, {doc.get('cores', 2)} cores:", "",
             "| scene | tuned on / held out | DSM MAE (m) | trees masked (m) | median (m) | completeness (%) | run time (s) |",
             "|---|---|---|---|---|---|---|"]
    lines += [row(s, False) for s in doc["scenes"]]
    return "\n".join(lines)


def update_record(record_path, path):
    """Puts the run's scenes into the record; returns the record."""
    doc = load(path)
    record = load(record_path) if os.path.isfile(record_path) else {
        "schema": "skyfall.accuracy_record/1", "scenes": []}
    by_name = {s["scene"]: s for s in record["scenes"]}
    date, commit = run_date(path, doc), doc.get("commit") or head_commit()
    for s in doc["scenes"]:
        entry = {k: s.get(k) for k in ROW_KEYS}
        entry.update(date=date, commit=commit, cores=doc.get("cores", 2))
        by_name[s["scene"]] = entry
    # Tuned-on scenes first, then the held-out ones, each by name.
    record["scenes"] = sorted(by_name.values(), key=lambda s: (not s.get("tuned_on"), s["scene"]))
    tmp = record_path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(record, f, indent=2)
        f.write("\n")
    os.replace(tmp, record_path)
    return record


def record_block(record):
    lines = ["Each scene's latest 256 m run with the defaults, 2 cores, dated (a row predates what changed",
             "after its date):", "",
             "| scene | tuned on / held out | DSM MAE (m) | trees masked (m) | median (m) | completeness (%) | run time (s) | measured |",
             "|---|---|---|---|---|---|---|---|"]
    lines += [row(s, True) for s in record["scenes"]]
    return "\n".join(lines)


def main(argv):
    args = argv[1:]
    record_path = None
    if args[:1] == ["--record"]:
        if len(args) < 2:
            sys.exit(__doc__.strip().splitlines()[2])
        record_path, args = args[1], args[2:]
    if len(args) not in (1, 2):
        sys.exit(__doc__.strip().splitlines()[2])
    readme = args[1] if len(args) == 2 else os.path.join(os.path.dirname(__file__), "..", "README.md")
    with open(readme) as f:
        text = f.read()
    start, end = text.find(BEGIN), text.find(END)
    if start < 0 or end < start:
        sys.exit(f"readme_results: {readme}: no {BEGIN} ... {END} block")
    table = record_block(update_record(record_path, args[0])) if record_path else block(args[0])
    new = text[:start + len(BEGIN)] + "\n" + table + "\n" + text[end:]
    if new != text:
        tmp = readme + ".tmp"
        with open(tmp, "w") as f:
            f.write(new)
        os.replace(tmp, readme)


if __name__ == "__main__":
    main(sys.argv)
