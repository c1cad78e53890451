"""`coadapt dashboard` in a real browser (headless Chromium through the system's
chromedriver): each page shows the store's numbers (best design, improvement +- SE, front
size, hypervolume, cell states), hostile strings show as text and never run, a path out of a
run folder is refused, a deleted run folder is said, and a running run's page shows its new
rows without a reload. A screenshot of each page goes into the test's output folder
($COADAPT_DASHBOARD_SCREENSHOTS as well when set: docs/dashboard/ is made that way)."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from coadapt_core.errors import UserError
from coadapt_core.results import ResultsStore
from tests.core.test_dashboard_support import PAYLOAD, Browser, Served, add_run, needs_browser

pytestmark = needs_browser
ROOT = Path(__file__).resolve().parents[2]
SINGLE = "20261201-100000-ours-pso-torque-s0-aaaaaa"
MULTI = "20261201-101500-ours-nsga2-torque+power-s1-bbbbbb"
HOSTILE = "20261201-103000-ours-pso-torque-s2-cccccc"
GONE = "20261201-104500-ours-pso-torque-s3-dddddd"
RUNNING = "20261201-106000-ours-pso-torque-s4-eeeeee"
GRID = "grid-20261201-demo"
SUMMARY = {
    "best_design": [0.612, 0.587],
    "best_cost": 1.0123,
    "best_cost_se": 0.004,
    "nominal_cost": 1.155,
    "nominal_cost_se": 0.005,
    "final_interactions": 4000,
    "improvement": 0.1234,
    "improvement_se": 0.0081,
    "improvement_plain": 0.101,
    "improvement_plain_se": 0.009,
    "best_fall_rate": 0.02,
    "nominal_fall_rate": 0.004,
    "fall_rate_difference": 0.016,
    "fall_rate_difference_se": 0.005,
    "numerics": {
        "precision": "bf16",
        "pseudo_precision": "bf16",
        "rollout_precision": "float32",
        "device": "cpu",
        "processor": "AMD EPYC 9B14",
        "bf16_native": True,
        "threads": 2,
        "torch": "2.13.0",
        "engine": "mujoco",
        "engine_version": "4.0.0",
    },
}
FRONT = {
    "designs": [[0.6, 0.6], [0.9, 0.8], [1.2, 1.0]],
    "costs": [
        {"torque": 1.0, "power": 3.0},
        {"torque": 1.5, "power": 2.2},
        {"torque": 2.4, "power": 2.0},
    ],
    "costs_se": [{"torque": 0.02, "power": 0.05}] * 3,
    "hypervolume": 0.4321,
    "hypervolume_se": 0.0123,
}


#: each chart of a page: its title, axis titles and the labels of its series
CHARTS = """return [...document.querySelectorAll('svg.chart')].map(s => ({
  title: s.getAttribute('aria-label'),
  x: s.querySelector('.x-title').textContent, y: s.querySelector('.y-title').textContent,
  series: [...s.querySelectorAll('g.series')].map(g => g.dataset.label)}));"""


def shots(tmp: Path) -> list[Path]:
    out = [tmp]
    if os.environ.get("COADAPT_DASHBOARD_SCREENSHOTS"):
        out.append(Path(os.environ["COADAPT_DASHBOARD_SCREENSHOTS"]))
    return out


def shoot(browser: Browser, tmp: Path, name: str) -> None:
    first = browser.screenshot(tmp / f"{name}.png")
    for other in shots(tmp)[1:]:
        other.mkdir(parents=True, exist_ok=True)
        shutil.copy(first, other / f"{name}.png")


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    """A store with a finished run, a multi-objective run, a grid, a hostile run, a run whose
    folder was deleted and a running one; a browser; the dashboard serving the store."""
    tmp = tmp_path_factory.mktemp("dashboard")
    runs, db = tmp / "runs", tmp / "s.db"
    with ResultsStore(db) as store:
        cell = {"grid_id": GRID, "grid_cell": "ours/torque/flat/s0"}
        add_run(store, SINGLE, runs, summary=SUMMARY, extra=cell)
        front_summary = {**SUMMARY, "pareto_front": FRONT, "best_costs": FRONT["costs"][1]}
        cell = {"grid_id": GRID, "grid_cell": "ours/torque+power/flat/s1"}
        add_run(
            store,
            MULTI,
            runs,
            objectives=("torque", "power"),
            seed=1,
            summary=front_summary,
            extra=cell,
        )
        add_run(store, RUNNING, runs, seed=4, status="running")
        add_run(store, GONE, runs, seed=3, summary=SUMMARY)
        shutil.rmtree(runs / GONE)
        hostile = {"robot": PAYLOAD, "terrain": PAYLOAD, "note": PAYLOAD}
        add_run(
            store, HOSTILE, runs, seed=2, summary={**SUMMARY, "warnings": [PAYLOAD]}, extra=hostile
        )
        store.create_run({"method": "ours", "robot": PAYLOAD}, run_id=PAYLOAD, run_dir="/etc")
        store.save_grid(GRID, {"methods": ["ours"]})
        side = {"improvement_se": 0.01, "improvement_plain": 0.1}
        store.record_verification(
            SINGLE,
            {
                "key": "b1000000-s0",
                "budget": 1_000_000,
                "seed": 0,
                "scenarios": 128,
                "designs": [
                    {
                        "role": "best",
                        "design": SUMMARY["best_design"],
                        "objective": "torque",
                        "specialist": {**side, "improvement": 0.0987},
                        "universal": {**side, "improvement": 0.1234},
                        "difference": -0.0247,
                        "difference_se": 0.006,
                        "verdict": "shrinks",
                        "line": "best: shrinks",
                    }
                ],
            },
        )
        store.set_cell(GRID, "ours/torque/flat/s0", status="finished", run_id=SINGLE, attempt=True)
        store.set_cell(
            GRID, "ours/torque+power/flat/s1", status="finished", run_id=MULTI, attempt=True
        )
        store.set_cell(GRID, "ours/torque/rough/s0", status="failed", error=PAYLOAD, attempt=True)
        store.set_cell(GRID, "ours/torque/rough/s1", status="running", run_id=RUNNING, attempt=True)
        store.set_cell(GRID, "ours/torque/rough/s1", status="running", attempt=True)  # ran again
        store.set_cell(GRID, "ours/power/flat/s0", status="pending")
    before = hashlib.sha256(db.read_bytes()).hexdigest()
    served = Served(db)
    browser = Browser()
    yield {"served": served, "browser": browser, "tmp": tmp, "url": served.url}
    browser.close()
    served.close()
    assert hashlib.sha256(db.read_bytes()).hexdigest() == before, "the store file changed"


def test_runs_page_lists_every_run_with_its_numbers(world):
    b = world["browser"]
    b.go(world["url"])
    table = b.wait_text("#runs", contains=SINGLE)
    assert "6 runs" in b.text("#run-count")
    row = next(line for line in table.splitlines() if SINGLE in line)
    assert "finished" in row and "thigh_scale 0.612, shank_scale 0.587" in row
    assert "12.3% ± 0.8% SE (n=1)" in row  # improvement +- SE as `coadapt report` writes it
    assert "+1.6 ± 0.5 points SE (n=1)" in row  # fall-rate difference, in points
    running = next(line for line in table.splitlines() if RUNNING in line)
    assert "running" in running and "outer 2/2" in running and "36,000 interactions" in running
    assert GRID in b.text("#grids") and "2 finished" in b.text("#grids")
    shoot(b, world["tmp"], "runs")


def test_hostile_strings_show_as_text_and_never_run(world):
    b = world["browser"]
    b.go(world["url"])
    b.wait_text("#runs", contains=HOSTILE)
    assert PAYLOAD in b.text("#runs")  # the markup is shown, letter for letter
    b.go(world["url"] + "run/" + HOSTILE)
    config = b.wait_text("#config", contains="note", shown=False)  # folded away by default
    assert PAYLOAD.replace('"', '\\"') in config
    assert PAYLOAD in b.text("#summary")
    assert b.run(
        "return [window.pwned === undefined, document.title, document.images.length];"
    ) == [
        True,
        "coadapt dashboard",
        1,  # the run's GIF only: no <img> from the store
    ]


def test_a_runs_page_shows_its_report_numbers_charts_gif_and_commands(world):
    b = world["browser"]
    b.go(world["url"] + "run/" + SINGLE)
    summary = b.wait_text("#summary", contains="improvement")
    assert "thigh_scale 0.612, shank_scale 0.587" in summary
    assert "12.3% ± 0.8% SE (n=1)" in summary and "10.1% ± 0.9% SE (n=1)" in summary
    assert "1.0123 ± 0.004 SE (n=1)" in summary
    assert (
        "2.0% / 0.4%" in summary.replace(" SE (n=1)", "").replace(" ± 0.0%", "")
        or "2.0%" in summary
    )
    assert b.text("#eval-count").startswith("20 rows: 16 real, 4 surrogate")
    assert "+1.6 ± 0.5 points SE (n=1)" in summary  # a fall-rate difference is in points
    # `coadapt verify`'s verdict line (the store's verifications row)
    assert b.text("td[data-field=verification]") == (
        "best: shrinks (1,000,000 interactions per specialist)"
    )
    assert b.text("td[data-field=numerics]") == (
        "bf16 learner (pseudo-critics bf16, rollouts float32) on CPU AMD EPYC 9B14 "
        "(bf16 native), 2 threads; torch 2.13.0, mujoco 4.0.0"
    )
    # convergence, designs, surrogate error, training reward, and what the learner measured:
    # one chart per unit (speed and tracking error in m/s, episode length in s)
    charts = {c["title"]: c for c in b.run(CHARTS)}
    axes = {title: (c["x"], c["y"]) for title, c in charts.items()}
    assert axes == {
        "Convergence: best in-run torque cost so far": (
            "environment interactions",
            "torque cost per step [(Nm)^2]",
        ),
        "Evaluated designs, coloured by torque cost (circle: real, square: surrogate)": (
            "thigh_scale [x 0.35 m]",  # the design variables with their units
            "shank_scale [x 0.35 m]",
        ),
        "Surrogate error by round (surrogate − real, % of real)": (
            "outer iteration",
            "relative error (%)",
        ),
        "Training phases: final mean reward": (
            "training interactions (cumulative)",
            "mean reward per step",
        ),
        "Training phases: forward speed and velocity tracking error": (
            "training interactions (cumulative)",
            "m/s",
        ),
        "Training phases: episode length": ("training interactions (cumulative)", "s"),
    }
    speed = charts["Training phases: forward speed and velocity tracking error"]["series"]
    assert speed == ["forward speed (m/s)", "tracking error |v_cmd − v| (m/s)"]
    assert charts["Training phases: episode length"]["series"] == ["episode length (s)"]
    # the convergence chart has what the run folder's convergence.png has: the final check
    # +- its SE after the curve, by the check's own interactions, and the nominal line
    convergence = charts["Convergence: best in-run torque cost so far"]
    assert convergence["series"] == [
        "in-run best (own scenarios)",
        "final check ± SE (fresh scenarios)",
        "nominal design (final check)",
    ]
    final = b.run(
        "const g = document.querySelector('svg.chart g.series[data-label^=\"final check\"]');"
        "return [g.querySelector('title').textContent, g.querySelectorAll('line').length];"
    )
    # 2 phases of 10 000 steps + 16 real evaluations of 1 000, then the check's 4 000
    assert final == ["final check ± SE (fresh scenarios) (40000, 1.012) ± 0.004", 1]
    nominal = b.run(
        "const g = document.querySelector('svg.chart g.series[data-label^=\"nominal\"] path');"
        "return [g.getAttribute('stroke-dasharray'), g.getAttribute('d')];"
    )
    assert nominal[0] == "2,4"
    ys = {p.split(",")[1] for p in nominal[1][1:].split("L")}
    assert len(ys) == 1  # a horizontal line
    assert b.run("return document.querySelector('img.gif').naturalWidth;") == 1
    commands = b.text("#commands")
    assert f"coadapt run --resume {world['tmp'] / 'runs' / SINGLE}" in commands
    assert "coadapt handoff" in commands
    shoot(b, world["tmp"], "run")


def test_a_multi_objective_runs_page_shows_its_front_and_hypervolume(world):
    b = world["browser"]
    b.go(world["url"] + "run/" + MULTI)
    pareto = b.wait_text("#pareto", contains="hypervolume")
    assert "front designs\t3" in pareto
    assert "hypervolume 0.432 +- 0.012" in pareto
    assert len(b.text("#front").splitlines()) == 4  # header + 3 designs
    assert "--pick knee" in b.text("#commands")
    shoot(b, world["tmp"], "pareto")


def test_a_grids_page_shows_its_cells_by_state_and_the_tables(world):
    b = world["browser"]
    b.go(world["url"] + "grid/" + GRID)
    states = b.wait_text("#cell-states")
    for part in ("2 finished", "1 failed", "1 running", "1 pending"):
        assert part in states
    cells = b.text("#cells")
    again = next(line for line in cells.splitlines() if "rough/s1" in line)
    assert "\t2\tyes\t" in again  # the cell that ran again
    assert PAYLOAD in cells  # the failed cell's error, as text
    body = b.text("main")
    assert "Table 6 — optimization results" in body and "Table 7 — computational cost" in body
    assert "Beside the paper" in body and "12.3% ± 0.8% SE (n=1)" in body
    # `coadapt verify`'s column: the improvement with specialists, the universal one beside it
    assert "with specialists (universal): verdict" in body
    assert "9.9% ± 1.0% SE (n=1) (universal 12.3% ± 1.0% SE (n=1)): shrinks" in body
    shoot(b, world["tmp"], "grid")
    b.go(world["url"] + "?grid=" + GRID)  # the link to its runs: the runs table filtered
    assert b.wait_text("#run-count").startswith("2 runs")
    assert SINGLE in b.text("#runs") and HOSTILE not in b.text("#runs")
    b.go(world["url"] + "?q=" + SINGLE)  # one run: "1 run", not "1 runs"
    assert b.wait_text("#run-count") == "1 run of 6 shown (the store: 4 finished, 2 running)"


def test_the_compare_page_sets_runs_side_by_side(world):
    b = world["browser"]
    b.go(f"{world['url']}compare?run={SINGLE}&run={MULTI.replace('+', '%2B')}")
    table = b.wait_text("#compare-table", contains=MULTI)
    assert SINGLE in table
    assert "torque, power" in table and "12.3% ± 0.8% SE (n=1)" in table
    # one curve: a multi-objective run has no single best-cost curve (the report draws none)
    assert b.run("return document.querySelectorAll('svg.chart .series').length;") == 1
    shoot(b, world["tmp"], "compare")


def test_paths_out_of_run_folders_and_deleted_folders_are_said_in_the_page(world):
    b = world["browser"]
    for path in (f"files/{SINGLE}/..%2F..%2Fs.db", f"files/{SINGLE}/%2Fetc%2Fpasswd"):
        b.go(world["url"] + path)
        assert "refused" in b.wait_text("#error")
    b.go(world["url"] + "files/" + PAYLOAD.replace("<", "%3C").replace(">", "%3E") + "/x.gif")
    assert "not a run id" in b.wait_text("#error")
    b.go(world["url"] + "run/" + GONE)
    assert "deleted or moved" in b.wait_text("#folder-state")
    assert "12.3% ± 0.8% SE (n=1)" in b.text("#summary")  # the store's numbers still show


def test_a_running_runs_page_shows_new_rows_within_10_s_without_a_reload(world, tmp_path):
    """A real quick run (the analytic fake learner, each phase 1.5 s) writes its rows while
    its page is open; each new row is on the page within 10 s of its commit."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "FAKE_DELAY": "1.5"}
    args = ["--out", "runs", "--store", "live.db", "--no-video", "--outer-iterations", "2"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "tests.fakes.fake_learner_cli", "run", "--preset", "smoke", *args],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    served = None
    try:
        deadline = time.monotonic() + 120  # a loaded CI machine starts the run slowly
        while not (tmp_path / "live.db").exists() or not list((tmp_path / "runs").glob("*")):
            assert time.monotonic() < deadline and proc.poll() is None
            time.sleep(0.2)
        run_id = next((tmp_path / "runs").iterdir()).name
        while served is None:  # the store's tables may still be in the making
            try:
                served = Served(tmp_path / "live.db")
            except UserError:
                assert time.monotonic() < deadline and proc.poll() is None
                time.sleep(0.2)
        b = world["browser"]
        b.go(served.url + "run/" + run_id)
        b.wait_text("#eval-count")
        b.run("window.sameDocument = true;")
        lags = []
        shown = int(b.run("return document.querySelector('#eval-count').dataset.rows;"))
        while proc.poll() is None and time.monotonic() < deadline:
            stored = served.store.count_evaluations(run_id)
            if stored > shown:  # a new row is committed: the page must show it within 10 s
                committed = time.monotonic()
                while (
                    int(b.run("return document.querySelector('#eval-count').dataset.rows;"))
                    < stored
                ):
                    assert time.monotonic() - committed < 10, "the page missed a new row for 10 s"
                    time.sleep(0.2)
                lags.append(time.monotonic() - committed)
                shown = stored
            time.sleep(0.2)
        assert proc.wait(timeout=60) == 0
        assert lags, "the run wrote its rows before the page could watch them"
        print(f"new rows shown {len(lags)} times, after {max(lags):.1f} s at most")
        assert b.run("return window.sameDocument === true;")  # never reloaded
        b.wait_text("#summary", timeout=15, contains="finished")
        b.go(served.url)  # a store of one run says so in the singular
        assert b.wait_text("#run-count") == "1 run: 1 finished"
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(timeout=20)
        if served is not None:
            served.close()
