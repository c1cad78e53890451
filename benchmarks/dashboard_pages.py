"""How fast `coadapt dashboard` serves its pages from a big store: the runs page and a run's
page (each its HTML shell plus the JSON it draws, over HTTP from the dashboard's own server)
on the store `dashboard_store.py` makes (10 000 runs, 1 000 000 evaluations), against the
limit of 1 s each.

    python benchmarks/dashboard_store.py /tmp/big.db        # once (about a minute)
    python benchmarks/dashboard_pages.py /tmp/big.db        # the timing, one JSON line

Each page is fetched `--repeat` times after one first fetch (a cold cache: the first request
after start); the JSON gives the first, the median and the slowest of the rest, for the
default runs page (newest first), the runs page sorted by improvement, a search, the
newest run's page and the oldest run's page, and whether every one is under the limit.
"""

from __future__ import annotations

import argparse
import json
import statistics
import threading
import time
import urllib.request
from pathlib import Path

import sqlalchemy as sa

from coadapt_core.dashboard.files import RunFolders
from coadapt_core.dashboard.readonly import ReadOnlyStore
from coadapt_core.dashboard.server import start
from coadapt_core.results.schema import evaluations, runs

LIMIT_S = 1.0


def fetch(url: str) -> float:
    """Seconds to fetch `url` whole (status 200 required)."""
    t = time.perf_counter()
    with urllib.request.urlopen(url, timeout=60) as response:
        response.read()
        assert response.status == 200, url
    return time.perf_counter() - t


def page_time(base: str, shell: str, data: str) -> float:
    """A page as the browser loads it: its shell, then the JSON its script asks for."""
    return fetch(base + shell) + fetch(base + data)


def measure(base: str, shell: str, data: str, repeat: int) -> dict[str, float]:
    first = page_time(base, shell, data)
    times = [page_time(base, shell, data) for _ in range(repeat)]
    return {"first_s": first, "median_s": statistics.median(times), "max_s": max(times)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("store", type=Path, help="the store dashboard_store.py made")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    store = ReadOnlyStore(str(args.store))
    with store.engine.connect() as conn:
        n_runs = conn.execute(sa.select(sa.func.count()).select_from(runs)).scalar_one()
        n_evals = conn.execute(sa.select(sa.func.count()).select_from(evaluations)).scalar_one()
        newest = conn.execute(sa.select(runs.c.id).order_by(runs.c.created_at.desc())).first()[0]
        oldest = conn.execute(sa.select(runs.c.id).order_by(runs.c.created_at)).first()[0]
    server = start(store, RunFolders(None), "127.0.0.1", 0)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    base = server.url.rstrip("/")
    pages = {
        "runs_page": ("/", "/api/runs"),
        "runs_page_by_improvement": ("/?sort=improvement", "/api/runs?sort=improvement"),
        "runs_page_search": ("/?q=tracking", "/api/runs?q=tracking&status=finished"),
        "run_page_newest": (f"/run/{newest}", f"/api/run/{newest}"),
        "run_page_oldest": (f"/run/{oldest}", f"/api/run/{oldest}"),
    }
    try:
        results = {name: measure(base, *urls, args.repeat) for name, urls in pages.items()}
    finally:
        server.shutdown()
        server.server_close()
        store.close()
    slowest = max(max(r["first_s"], r["max_s"]) for r in results.values())
    print(
        json.dumps(
            {
                "store": str(args.store),
                "runs": n_runs,
                "evaluations": n_evals,
                "limit_s": LIMIT_S,
                "runs_page_s": results["runs_page"]["median_s"],
                "run_page_s": results["run_page_newest"]["median_s"],
                "slowest_s": slowest,
                "under_limit": slowest < LIMIT_S,
                "pages": results,
            }
        )
    )


if __name__ == "__main__":
    main()
