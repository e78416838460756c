#!/usr/bin/env bash
# Regenerates the run configuration reference in docs/cli.md (the block
# between the options markers) from the option registry, through
# `skyfall run --print-options-reference`. The tests fail while the block
# differs from what the registry says.
# Usage: scripts/update_cli_docs.sh [SKYFALL_BINARY]
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-build/bin/skyfall}
[ -x "$bin" ] || { echo "update_cli_docs: no $bin (build first: scripts/build.sh)" >&2; exit 2; }
reference=$(mktemp)
trap 'rm -f "$reference"' EXIT
"$bin" run --print-options-reference > "$reference"
python3 - docs/cli.md "$reference" <<'PY'
import os, sys
doc_path, ref_path = sys.argv[1], sys.argv[2]
begin = "<!-- options:begin (generated: skyfall run --print-options-reference) -->\n"
end = "<!-- options:end -->"
doc = open(doc_path, encoding="utf-8").read()
a, b = doc.find(begin), doc.find(end)
if a < 0 or b < a:
    sys.exit(f"update_cli_docs: {doc_path} lacks the options markers")
new = doc[: a + len(begin)] + open(ref_path, encoding="utf-8").read() + doc[b:]
if new != doc:
    tmp = doc_path + ".tmp"
    open(tmp, "w", encoding="utf-8").write(new)
    os.replace(tmp, doc_path)
    print(f"update_cli_docs: {doc_path} updated")
else:
    print(f"update_cli_docs: {doc_path} already current")
PY
