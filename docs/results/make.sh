#!/bin/bash
# Rebuild docs/results/ from a results store that holds the grid's runs and the report's rows.
#
#   docs/results/make.sh STORE [RUN_ID ...]
#   docs/results/make.sh --render          (render report/ again from the committed export)
#
# STORE: a store on which `coadapt report` has already computed the common-scenario and
# sim-to-sim rows (they need the run folders and take minutes per run). RUN_IDs: the runs to
# publish (default: every finished run). Writes docs/results/export/ (the store's tables as
# CSV) and docs/results/report/ (tables and figures), the latter rendered from an import of
# the former into an empty store, exactly as tests/test_results_reproduce.py does.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
render() {  # report/ from an import of export/ into an empty store
  local work
  work="$(mktemp -d)"
  coadapt import "$here/export" --store "$work/results.db"
  # run folders may exist on this machine; the report is rendered where they do not matter:
  # only its tables (Markdown, CSV) and figures (PNG) are kept, not report.html or videos
  coadapt report --store "$work/results.db" -o "$work/report"
  rm -rf "$here/report" && mkdir -p "$here/report"
  cp "$work"/report/*.md "$work"/report/*.csv "$work"/report/*.png "$here/report/"
  rm -rf "$work"
}
if [ "${1:-}" = "--render" ]; then render; exit 0; fi
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
rm -rf "$here/export"
coadapt export --store "$store" -o "$here/export" "${runs[@]}"
render
