#!/bin/bash
# Rebuild docs/results/ from a results store that holds the grid's runs and the report's rows.
#
#   docs/results/make.sh STORE [RUN_ID ...]
#
# STORE: a store on which `coadapt report` has already computed the common-scenario and
# sim-to-sim rows (they need the run folders and take minutes per run). RUN_IDs: the runs to
# publish (default: every finished run). Writes docs/results/export/ (the store's tables as
# CSV) and docs/results/report/ (tables and figures), the latter rendered from an import of
# the former into an empty store, exactly as tests/test_results_reproduce.py does.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
store="$1"; shift
runs=()
for r in "$@"; do runs+=(--run "$r"); done
if [ ${#runs[@]} -eq 0 ]; then
  while read -r r; do runs+=(--run "$r"); done < <(python - "$store" <<'PY'
import sys
from coadapt_core.results.store import ResultsStore
store = ResultsStore(sys.argv[1])
for run in store.table_rows("runs", None):
    if run["status"] == "finished":
        print(run["id"])
PY
)
fi
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
rm -rf "$here/export" "$here/report"
coadapt export --store "$store" -o "$here/export" "${runs[@]}"
coadapt import "$here/export" --store "$work/results.db"
# run folders may exist on this machine; the report is rendered where they do not matter:
# only its tables (Markdown, CSV) and figures (PNG) are kept, not report.html or videos
coadapt report --store "$work/results.db" -o "$work/report"
mkdir -p "$here/report"
cp "$work"/report/*.md "$work"/report/*.csv "$work"/report/*.png "$here/report/"
