"""A Pareto front you can trust and pick from (issue 43): the stored front with its final-check
errors, the design the run returns, the hypervolume with its paired bootstrap SE, the plots
every run leaves in its folder (drawn by the report's functions), and `--pick`'s rules. The
loop's logic runs on the analytic fake with per-scenario costs."""

from __future__ import annotations

import json

import numpy as np
import pytest

import coadapt_core.coadapt.setup as loop_setup
from coadapt_core.cli import main
from coadapt_core.pareto import (
    HV_REFERENCE,
    hypervolume,
    hypervolume_se,
    is_dominated,
    pick_index,
    relative_costs,
)
from tests.fakes.analytic import AnalyticBackend

NSGA2 = [
    "run",
    "--optimizer",
    "nsga2",
    "--objective",
    "power,torque",
    "--preset",
    "smoke",
    "--population",
    "8",
    "--optimizer-iterations",
    "4",
    "--no-video",
]


def _area(points: np.ndarray, ref: float) -> float:
    """The 2-D dominated area up to (ref, ref), by sweeping the points sorted by x (no pymoo)."""
    pts = sorted(map(tuple, points[(points < ref).all(axis=1)]))
    area, best_y = 0.0, ref
    for x, y in pts:
        if y < best_y:
            area += (ref - x) * (best_y - y)
            best_y = y
    return area


@pytest.fixture
def paired_fake(monkeypatch):
    monkeypatch.setattr(
        loop_setup,
        "universal_policy_factory",
        lambda *a, **k: lambda seed: AnalyticBackend(seed, paired=True),
    )


@pytest.fixture
def nsga2_run(tmp_path, capsys, paired_fake):
    assert main([*NSGA2, "--out", str(tmp_path / "runs"), "--store", "none"]) == 0
    (run_dir,) = (tmp_path / "runs").iterdir()
    return run_dir, json.loads((run_dir / "summary.json").read_text()), capsys.readouterr()


def test_nsga2_run_leaves_its_front_plot_and_a_hypervolume_with_se(nsga2_run):
    run_dir, summary, captured = nsga2_run
    png = run_dir / "pareto.png"
    assert (
        png.is_file()
        and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        and png.stat().st_size > 10_000
    )
    assert f"figures: pareto.png in {run_dir}" in captured.err
    front = summary["pareto_front"]
    names = ["power", "torque"]
    costs = np.array([[c[n] for n in names] for c in front["costs"]])
    ses = np.array([[c[n] for n in names] for c in front["costs_se"]])
    assert len(costs) >= 2 and np.isfinite(ses).all() and (ses > 0).all()
    for i, point in enumerate(costs):  # non-dominated, sorted by the first cost
        assert not is_dominated(point, np.delete(costs, i, axis=0))
    assert (np.diff(costs[:, 0]) >= 0).all()
    # the design the run returns is the front's first, and the summary's best
    assert front["returned"] == 0 and summary["best_design"] == front["designs"][0]
    assert [summary["best_costs"][n] for n in names] == costs[0].tolist()
    hv, se = front["hypervolume"], front["hypervolume_se"]
    assert np.isfinite(hv) and hv > 0 and np.isfinite(se) and se >= 0
    assert se > 0  # 8 paired scenarios with spread: the bootstrap has something to measure
    # the number is the area the front dominates in nominal-relative costs (checked without pymoo)
    nominal = np.array([summary["nominal_costs"][n] for n in names])
    assert hv == pytest.approx(_area(relative_costs(costs, nominal), HV_REFERENCE), rel=1e-9)
    assert hv > 1.0  # the fake's front beats the nominal design (alone: 1)
    assert "hypervolume" in captured.out and f"{hv:.3f} +- {se:.3f}" in captured.out


def test_a_single_objective_run_leaves_its_convergence_plot_with_the_final_check(
    tmp_path, capsys, paired_fake
):
    from coadapt_core.analysis.facts import run_facts
    from coadapt_core.analysis.report_figures import convergence_series
    from coadapt_core.analysis.run_figures import FolderRecords, run_row
    from coadapt_core.results import ResultsStore

    db = tmp_path / "s.db"
    assert (
        main(
            [
                "run",
                "--preset",
                "smoke",
                "--population",
                "4",
                "--optimizer-iterations",
                "2",
                "--out",
                str(tmp_path / "runs"),
                "--store",
                str(db),
                "--no-video",
                "--json",
            ]
        )
        == 0
    )
    (run_dir,) = (tmp_path / "runs").iterdir()
    assert (run_dir / "convergence.png").is_file() and not (run_dir / "pareto.png").exists()
    # the run folder's records give the report's functions the same series as the store
    store = ResultsStore(db)
    (run,) = store.list_runs()
    from_store = convergence_series(store, run_facts(store, run))
    records = FolderRecords(run_dir)
    summary = json.loads((run_dir / "summary.json").read_text())
    import yaml

    from_folder = convergence_series(
        records,
        run_facts(
            records,
            run_row(run_dir, yaml.safe_load((run_dir / "config.yaml").read_text()), summary),
        ),
    )
    assert len(from_store[0]) >= 2
    np.testing.assert_array_equal(from_folder[0], from_store[0])
    np.testing.assert_array_equal(from_folder[1], from_store[1])


def test_hypervolume_is_measured_against_the_nominal_design():
    nominal = np.array([2.0, 10.0])
    assert hypervolume(nominal[None], nominal) == pytest.approx(1.0)  # the nominal design alone
    front = np.array([[1.0, 15.0], [3.0, 5.0]])  # relative (0.5, 1.5) and (1.5, 0.5)
    assert hypervolume(front, nominal) == pytest.approx(
        1.5 * 0.5 + 0.5 * 1.5 - 0.5 * 0.5
    )  # two boxes less their overlap
    assert hypervolume(front, nominal) == pytest.approx(
        _area(relative_costs(front, nominal), HV_REFERENCE)
    )
    assert (
        hypervolume(np.array([[5.0, 25.0]]), nominal) == 0.0
    )  # beyond twice the nominal cost: nothing
    # a dominated design adds nothing
    assert hypervolume(np.vstack([front, [[3.5, 16.0]]]), nominal) == pytest.approx(
        hypervolume(front, nominal)
    )


def test_hypervolume_se_is_paired_over_scenarios():
    rng = np.random.default_rng(0)
    true = np.array([[0.8, 1.1], [1.1, 0.8], [1.0, 1.0]])  # two front designs, the nominal last
    shared = rng.normal(0.0, 0.3, size=(1, 32, 2))  # what the scenarios share (paired)
    own = rng.normal(0.0, 0.02, size=(3, 32, 2))
    mean = lambda v: v.mean(axis=1)  # noqa: E731
    hv, se = hypervolume_se(true[:, None, :] + shared + own, mean)
    _, se_unpaired = hypervolume_se(true[:, None, :] + rng.normal(0.0, 0.3, size=(3, 32, 2)), mean)
    assert 0 < se < se_unpaired  # pairing cancels what the designs share
    assert hv == pytest.approx(
        hypervolume(
            mean(true[:, None, :] + shared + own)[:2], mean(true[:, None, :] + shared + own)[2]
        )
    )
    assert hypervolume_se(true[:, None, :], mean)[1] == 0.0  # one scenario: nothing to resample


def test_pick_takes_an_index_or_the_knee():
    costs = np.array([[1.0, 10.0], [2.0, 4.0], [6.0, 3.0], [10.0, 1.0]])
    assert pick_index("1", costs) == 1 and pick_index(3, costs) == 3
    assert pick_index("knee", costs) == 1  # scaled: (0.11, 0.33) is nearest (0, 0)
    for bad, says in (("4", "0 to 3"), ("-1", "0 to 3"), ("best", "nor 'knee'")):
        with pytest.raises(ValueError, match=says):
            pick_index(bad, costs)


def test_handoff_pick_refuses_in_one_line(nsga2_run, tmp_path, capsys):
    from coadapt_core.handoff.policy import missing_deploy_modules

    if missing_deploy_modules():
        pytest.skip("needs the deploy extra (coadapt[deploy])")
    run_dir, summary, _ = nsga2_run
    size = len(summary["pareto_front"]["designs"])
    for args, says in (
        (["--pick", str(size)], f"0 to {size - 1}"),
        (["--pick", "1", "--design", "1,1"], "give one"),
    ):
        assert main(["handoff", str(run_dir), "-o", str(tmp_path / "h"), *args]) == 2
        err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
        assert len(err) == 1 and "--pick" in err[0] and says in err[0], err
        assert not (tmp_path / "h").exists()


def test_the_report_compares_fronts_across_seeds(tmp_path, capsys, paired_fake):
    from coadapt_core.analysis.report import write_report
    from coadapt_core.results import ResultsStore

    db = tmp_path / "s.db"
    for seed in ("0", "1"):
        assert (
            main(
                [
                    *NSGA2,
                    "--seed",
                    seed,
                    "--out",
                    str(tmp_path / "runs"),
                    "--store",
                    str(db),
                    "--json",
                ]
            )
            == 0
        )
        line = json.loads(
            capsys.readouterr().out.strip().splitlines()[-1]
        )  # the --json line carries the hypervolume
        front = json.loads((tmp_path / "runs" / line["run_id"] / "summary.json").read_text())[
            "pareto_front"
        ]
        assert (line["hypervolume"], line["hypervolume_se"]) == (
            front["hypervolume"],
            front["hypervolume_se"],
        )
    with ResultsStore(db) as store:
        files = write_report(store, None, tmp_path / "rep", sim2sim=False)
        runs = store.list_runs()
    assert "pareto_seeds.png" in files and (tmp_path / "rep" / "pareto_seeds.png").is_file()
    hvs = np.array([r["summary"]["pareto_front"]["hypervolume"] for r in runs])
    text = (tmp_path / "rep" / "pareto.md").read_text()
    for r in runs:
        front = r["summary"]["pareto_front"]
        assert (
            f"| {r['id']} | {len(front['designs'])} | {front['hypervolume']:.3f} +- "
            f"{front['hypervolume_se']:.3f} |" in text
        )
    # the group of both seeds: their mean +- the SE over seeds
    mean, se = hvs.mean(), hvs.std(ddof=1) / np.sqrt(2)
    assert f"| 2 seeds |  | {mean:.3f} +- {se:.3f} |" in text
    assert "hypervolume" in (tmp_path / "rep" / "report.html").read_text()


@pytest.mark.slow
def test_a_real_nsga2_run_leaves_its_plots_and_hands_off_its_second_front_design(tmp_path, capsys):
    """Real physics (MuJoCo, the shipped policy fine-tuned a few hundred steps): the run's
    folder holds pareto.png, its summary a hypervolume with SE over a non-dominated front, and
    `coadapt handoff RUN --pick 1` writes a folder for the front's second design."""
    from coadapt_core.handoff.policy import missing_deploy_modules

    if missing_deploy_modules():
        pytest.skip("needs the deploy extra (coadapt[deploy])")
    args = [
        "run",
        "--optimizer",
        "nsga2",
        "--objective",
        "power,torque",
        "--sim",
        "mujoco",
        "--preset",
        "smoke",
        "--population",
        "4",
        "--agents-per-design",
        "2",
        "--eval-steps",
        "10",
        "--train-steps",
        "100",
        "--retrain-steps",
        "50",
        "--store",
        "none",
        "--out",
        str(tmp_path / "runs"),
        "--no-video",
        "--json",
    ]
    assert main(args) == 0
    (run_dir,) = (tmp_path / "runs").iterdir()
    assert (run_dir / "pareto.png").is_file()
    front = json.loads((run_dir / "summary.json").read_text())["pareto_front"]
    costs = np.array([[c["power"], c["torque"]] for c in front["costs"]])
    assert len(costs) >= 2  # 2 designs on this seed (1.46 +- 0.16 hypervolume when written)
    for i, point in enumerate(costs):
        assert not is_dominated(point, np.delete(costs, i, axis=0))
    assert np.isfinite(front["hypervolume"]) and front["hypervolume"] > 0
    assert np.isfinite(front["hypervolume_se"]) and front["hypervolume_se"] >= 0
    capsys.readouterr()
    out = tmp_path / "pick1"
    assert (
        main(
            [
                "handoff",
                str(run_dir),
                "-o",
                str(out),
                "--pick",
                "1",
                "--agents",
                "2",
                "--seconds",
                "0.5",
                "--no-check",
                "--no-video",
                "--sim",
                "mujoco",
                "--json",
            ]
        )
        == 0
    )
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert result["design"] == front["designs"][1]
    assert result["pareto_front_index"] == 1 and result["is_run_best"] is False
    sheet = json.loads((out / "design.json").read_text())
    assert (
        sheet["design"] == front["designs"][1]
        and (out / "robot.xml").is_file()
        and (out / "policy.onnx").is_file()
    )
    (own,) = [
        e
        for e in sheet["evaluations"]
        if e["source"] == "the run's final check (Pareto front design 1)"
    ]
    assert own["objectives"]["power"]["design"] == front["costs"][1]["power"]
    assert own["objectives"]["torque"]["design_se"] == front["costs_se"][1]["torque"]


def test_a_figure_that_cannot_be_drawn_is_one_line_and_the_result_stands(
    tmp_path, capsys, monkeypatch, paired_fake
):
    import coadapt_core.analysis.run_figures as run_figures

    def broken(*args, **kwargs):
        raise ValueError("no backend")

    monkeypatch.setattr(run_figures, "write_run_figures", broken)
    assert (
        main(
            [
                "run",
                "--preset",
                "smoke",
                "--population",
                "4",
                "--optimizer-iterations",
                "2",
                "--out",
                str(tmp_path / "runs"),
                "--store",
                "none",
                "--no-video",
                "--json",
            ]
        )
        == 0
    )
    captured = capsys.readouterr()
    assert [line for line in captured.err.splitlines() if line.startswith("figures:")] == [
        "figures: not drawn (ValueError: no backend)"
    ]
    (run_dir,) = (tmp_path / "runs").iterdir()
    assert json.loads((run_dir / "summary.json").read_text())["status"] == "finished"
    assert json.loads(captured.out.strip().splitlines()[-1])["run_id"] == run_dir.name


def test_the_hypervolume_se_matches_its_spread_over_independent_scenario_sets():
    """The bootstrap SE of one final check is the spread the hypervolume shows over 60
    independent scenario sets (the fake's paired costs under the capped rule): within 25 %."""
    from coadapt_core.coadapt.final_check import CostRule  # (the cost rule the final check uses)
    from coadapt_core.plugins import get_registry

    objectives = [get_registry().create("objective", name) for name in ("power", "torque")]
    designs = np.array(
        [[1.1, 0.8], [0.9, 0.7], [0.75, 0.65], [0.6, 0.6], [1.0, 1.0]]
    )  # the nominal last
    backend, rule = AnalyticBackend(0, paired=True), CostRule("capped")
    hvs, ses = [], []
    for seed in range(60):
        fit = backend.real_fitness(designs, objectives, agents=8, steps=10, seed=seed)
        reference = rule.reference(fit.per_scenario[-1], fit.scenario_falls[-1])
        hv, se = hypervolume_se(
            rule.scenario_values(fit.per_scenario, fit.scenario_falls, reference), rule.aggregate
        )
        hvs.append(hv)
        ses.append(se)
    spread = float(np.std(hvs, ddof=1))  # 0.0107 when written; mean SE 0.0110
    assert spread > 0 and np.mean(ses) == pytest.approx(spread, rel=0.25)


def _drawn(monkeypatch, module) -> list:
    """The figures `module` saves, kept open for reading instead of closed."""
    kept = []

    def keep(plt, fig, path, caption, *, layout=True):
        kept.append(fig)
        return [(path, caption)]

    monkeypatch.setattr(module, "save_figure", keep)
    return kept


def test_convergence_plot_has_its_unit_the_nominal_line_and_says_why_the_check_sits_higher(
    tmp_path, monkeypatch, paired_fake
):
    """Issue 50: the cost axis names its unit, the nominal design's final-check cost is a
    dotted line at its value, and the legend tells the in-run curve (biased low) from the
    final check's square (fresh scenarios)."""
    import coadapt_core.analysis.report_figures as report_figures
    from coadapt_core.analysis.run_figures import write_run_figures

    args = ["run", "--preset", "smoke", "--population", "4", "--no-video", "--store", "none"]
    assert main([*args, "--out", str(tmp_path / "runs")]) == 0
    (run_dir,) = (tmp_path / "runs").iterdir()
    summary = json.loads((run_dir / "summary.json").read_text())
    kept = _drawn(monkeypatch, report_figures)
    write_run_figures(run_dir, summary)
    (fig,) = kept
    ax = fig.axes[0]
    unit = summary["cost_units"]["torque"]
    assert unit and ax.get_ylabel() == f"torque cost per step [{unit}]"
    flat = [
        line for line in ax.lines if len(set(line.get_ydata())) == 1 and line.get_linestyle() == ":"
    ]
    assert [line.get_ydata()[0] for line in flat] == [pytest.approx(summary["nominal_cost"])]
    texts = [t.get_text() for legend in fig.legends for t in legend.get_texts()]
    assert texts[-3:] == [
        "in-run best (own scenarios, biased low)",
        "final check +- SE (fresh scenarios)",
        "nominal design (final check)",
    ]


def test_pareto_plot_names_the_unit_of_each_cost_axis(tmp_path, monkeypatch, nsga2_run):
    import coadapt_core.analysis.pareto_figure as pareto_figure
    from coadapt_core.analysis.run_figures import write_run_figures

    run_dir, summary, _ = nsga2_run
    kept = _drawn(monkeypatch, pareto_figure)
    write_run_figures(run_dir, summary)
    (fig,) = kept
    names = list(summary["best_costs"])
    units = summary["cost_units"]
    assert fig.axes[0].get_xlabel() == f"{names[0]} cost per step [{units[names[0]]}]"
    assert fig.axes[0].get_ylabel() == f"{names[1]} cost per step [{units[names[1]]}]"
