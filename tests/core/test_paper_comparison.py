"""`coadapt report` beside the paper: each Table 6, 7 and 9 cell of ours next to the paper's
figure with its verdicts (design direction, improvement within or outside, method order), in
Markdown, CSV and report.html, computed from known runs whose verdicts are worked out by hand."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from unittest import mock

import numpy as np
import pytest

from coadapt_core.analysis.paper_comparison import order_comparison, table6_comparison
from coadapt_core.analysis.paper_verdicts import direction, direction_verdict, value_verdict
from coadapt_core.analysis.report import write_report
from coadapt_core.fitness import TrainingResult
from coadapt_core.results import SqliteRecorder


def read_csv(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


def test_direction_and_value_verdicts():
    assert [direction(x) for x in (1.3, 1.02, 0.98, 0.7, None)] == [
        "longer",
        "nominal",
        "nominal",
        "shorter",
        None,
    ]
    assert (
        direction_verdict({"thigh": 1.3, "shank": 0.6}, {"thigh": 1.41, "shank": 0.54}) == "agrees"
    )
    assert (
        direction_verdict({"thigh": 0.8, "shank": 0.6}, {"thigh": 1.41, "shank": 0.54})
        == "disagrees (thigh)"
    )
    assert (
        direction_verdict({"thigh": 1.3, "shank": 0.99}, {"thigh": 1.41, "shank": 0.54})
        == "undecided (shank at nominal)"
    )
    assert direction_verdict({"thigh": None, "shank": 0.6}, {"thigh": 1.41, "shank": 0.54}) == "n/a"
    assert value_verdict(0.45, 0.01, 0.459) == "within"  # 0.9 pp off, 2 SE = 2 pp
    assert value_verdict(0.45, 0.004, 0.459) == "below"  # 0.9 pp off, 2 SE + rounding = 0.85 pp
    assert value_verdict(0.50, 0.01, 0.459) == "above"
    assert value_verdict(0.50, None, 0.459) == "above (no SE)"
    assert value_verdict(None, 0.01, 0.459) == "n/a" == value_verdict(0.5, 0.01, None)


def _row(
    method,
    improvement,
    std,
    n=3,
    objective="torque",
    terrain="flat",
    thigh=0.5,
    shank=0.5,
    plain=None,
):
    """A table6_rows row of the paper robot's continuous space."""
    row = {
        "objective": objective,
        "method": method,
        "optimizer": "pso",
        "terrain": terrain,
        "runs": n,
        "seeds": "0 1 2",
        "design_variables": "thigh_scale shank_scale",
        "design_units": "x|x",
        "design_discrete": "0 0",
        "thigh_scale": thigh,
        "thigh_scale_std": 0.01,
        "thigh_scale_n": n,
        "shank_scale": shank,
        "shank_scale_std": 0.01,
        "shank_scale_n": n,
        "improvement": improvement,
        "improvement_std": std,
        "improvement_n": n,
        "improvement_se": None,
        "improvement_plain": plain,
        "improvement_plain_std": None if plain is None else std,
        "improvement_plain_n": 0 if plain is None else n,
        "sim2sim_improvement": None,
        "sim2sim_improvement_std": None,
        "sim2sim_improvement_n": 0,
    }
    return row


def test_method_order_counts_reversed_pairs_and_skips_the_papers_ties():
    # torque on flat: paper ours 45.9, no-surrogate 46.5, no-real 43.6,
    # no-retrain 46.8 = BO 46.8 (a tie)
    rows = [
        _row("ours", 0.47, 0.01),
        _row("no-surrogate", 0.46, 0.01),
        _row("no-real", 0.30, 0.01),
        _row("no-retrain", 0.40, 0.01),
        _row("bo-specialized", 0.41, 0.01),
    ]
    comp = table6_comparison(rows)
    (order,) = order_comparison(comp)
    assert order["paper_order"].split(" > ")[:2] == [
        "no-retrain",
        "bo-specialized",
    ]  # tied, the paper's row order
    assert order["our_order"] == "ours > no-surrogate > bo-specialized > no-retrain > no-real"
    # 10 pairs, one tied in the paper; reversed: ours/no-surrogate (0.01 apart: within noise),
    # and no-retrain and BO each below ours and no-surrogate (4, each ~0.06 apart against
    # 2 x hypot(SE) = 0.016: clear)
    assert (order["pairs"], order["reversed"], order["clear_reversals"]) == (9, 5, 4)
    assert order["verdict"] == "5 of 9 pairs reversed (4 beyond 2 SE)"
    same = order_comparison(
        table6_comparison([_row("ours", 0.45, 0.01), _row("no-real", 0.40, 0.01)])
    )
    assert [o["verdict"] for o in same] == ["same order"]


def _record(
    rec: SqliteRecorder,
    method: str,
    seed: int,
    best: list[float],
    improvement: float,
    *,
    objective="torque",
    terrain="flat",
    optimizer="pso",
    plain: float | None = None,
    steps: int = 1000,
    evals: int = 4,
    commit: str | None = "c0ffee",
    slow: float = 1.0,
) -> str:
    """A finished run of the paper robot with a chosen best design and improvement, made by the
    code of git commit `commit` (the wall clock pairs runs of one commit only), on a machine
    `slow` times slower than the reference (every second is `slow` seconds)."""
    config = {
        "method": method,
        "objective": objective,
        "terrain": terrain,
        "seed": seed,
        "preset": "smoke",
        "sim": "mujoco",
        "robot": "kuafu",
        "optimizer": optimizer,
    }
    with mock.patch("coadapt_core.results.store.code_commit", return_value=commit):
        run_id = rec.start_run(config)
    rec.record_training(
        run_id, outer=0, result=TrainingResult(steps=steps, seconds=1.0 * slow, mean_reward=0.0)
    )
    designs = np.array([best] * evals)
    rec.record_evaluations(
        run_id,
        outer=0,
        inner=0,
        designs=designs,
        kind="real",
        interactions=100,
        seconds=0.5 * slow,
        costs=[{objective: 1.0}] * evals,
    )
    summary = {
        "best_design": best,
        "best_cost": 1.0,
        "nominal_cost": 2.0,
        "improvement": improvement,
    }
    if plain is not None:
        summary["improvement_plain"] = plain
    rec.finish(run_id, summary)
    return run_id


@pytest.fixture
def compared(tmp_path):
    rec = SqliteRecorder(tmp_path / "c.db")
    for s, (imp, plain) in enumerate(
        ((0.40, 0.42), (0.45, 0.47), (0.50, 0.52))
    ):  # mean 0.45, SE 0.05/sqrt(3)
        _record(rec, "ours", s, [0.50 + 0.02 * s, 0.55], imp, plain=plain, steps=3000, evals=4)
        _record(rec, "no-surrogate", s, [1.20, 0.60], 0.30 + 0.01 * s, steps=3000, evals=10)
    for s in range(2):  # Table 9: the mixed space (thigh, shank, hip motor, knee motor)
        _record(rec, "ours", s, [0.55, 0.52, 3, 2 + s], 0.30, optimizer="mixed-pso")
    return rec.store, write_report(rec.store, None, tmp_path / "rep", sim2sim=False)


def test_table6_beside_the_paper(compared):
    _, files = compared
    rows = {r["method"]: r for r in read_csv(files["paper_table6.csv"])}
    assert set(rows) == {"ours", "no-surrogate"}  # the mixed-space run is Table 9's
    ours, nos = rows["ours"], rows["no-surrogate"]
    assert float(ours["thigh"]) == pytest.approx(0.52) and float(ours["paper_thigh"]) == 0.51
    assert float(ours["thigh_se"]) == pytest.approx(0.02 / math.sqrt(3))
    assert ours["direction"] == "agrees"  # paper 0.51 / 0.54: both shorter; ours 0.52 / 0.55
    assert float(ours["improvement_se"]) == pytest.approx(0.05 / math.sqrt(3))
    assert (
        float(ours["paper_improvement"]) == pytest.approx(0.459)
        and ours["improvement_verdict"] == "within"
    )
    assert (
        float(ours["improvement_plain"]) == pytest.approx(0.47)
        and ours["improvement_plain_verdict"] == "within"
    )
    assert ours["sim2sim_verdict"] == "n/a" and float(
        ours["paper_sim2sim_improvement"]
    ) == pytest.approx(0.28)
    assert (
        nos["direction"] == "disagrees (thigh)"
    )  # 1.2 / 0.6 against 0.50 / 0.51: the shank is shorter in both
    assert (
        nos["improvement_verdict"] == "below" and nos["improvement_plain_verdict"] == "n/a"
    )  # no plain mean recorded
    (order,) = [o for o in read_csv(files["paper_order.csv"]) if o["measure"] == "improvement"]
    assert (
        order["paper_order"] == "no-surrogate > ours"
        and order["our_order"] == "ours > no-surrogate"
    )
    assert order["verdict"] == "1 of 1 pairs reversed (1 beyond 2 SE)"
    md = files["paper_comparison.md"].read_text()
    assert (
        "| τ | Ours | pso | flat | 3 | 0.52 ± 0.01 / 0.51 | 0.55 ± 0.00 / 0.54 | agrees "
        "| 45.0% ± 2.9 / 45.9% | within |" in md
    )
    assert "Paper cells with no run here: 43 of 45 (Table 6), 8 of 9 (Table 9): not yet run." in md
    assert "Du et al. 2025" in md


def test_table7_and_table9_beside_the_paper(compared):
    _, files = compared
    t7 = {r["method"]: r for r in read_csv(files["paper_table7.csv"])}
    assert set(t7) == {
        "ours",
        "no-surrogate",
    }  # the mixed-space runs are not in Table 7's comparison
    nos = t7["no-surrogate"]
    # ours 3000 + 400 interactions, no-surrogate 3000 + 1000: ratio 4000 / 3400; paper 132 / 102
    assert float(nos["interactions_ratio"]) == pytest.approx(4000 / 3400)
    assert float(nos["paper_interactions_ratio"]) == pytest.approx(132 / 102)
    assert (
        float(nos["evaluation_ratio"]) == pytest.approx(2.5)
        and float(nos["paper_evaluation_ratio"]) == 2.0
    )
    assert (
        nos["interactions_verdict"] == "costlier as in the paper"
        and t7["ours"]["interactions_verdict"] == "reference"
    )
    # wall clock: 1 s training + 4 x 0.5 s evaluation against 1 + 10 x 0.5
    assert (
        float(nos["time_ratio"]) == pytest.approx(6.0 / 3.0)
        and nos["time_verdict"] == "costlier as in the paper"
    )
    (t9,) = read_csv(files["paper_table9.csv"])
    assert (t9["objective"], t9["terrain"], t9["optimizer"], t9["runs"]) == (
        "torque",
        "flat",
        "mixed-pso",
        "2",
    )
    assert t9["direction"] == "agrees" and (t9["paper_thigh"], t9["paper_shank"]) == (
        "0.54",
        "0.53",
    )
    # a motor type is reported per seed, never averaged (knee types 2 and 3 would read as 2.5)
    assert (t9["hip_motor"], t9["hip_motor_verdict"]) == ("3 3", "same")
    assert (t9["knee_motor"], t9["knee_motor_verdict"]) == (
        "2 3",
        "same in 1 of 2 seeds",
    )  # the paper's knee is 2
    assert (
        float(t9["paper_improvement"]) == pytest.approx(0.335)
        and t9["improvement_verdict"] == "below"
    )  # 30 % at both seeds
    html = files["report.html"].read_text()
    assert "| 3 3 / 3 (same) |" in files["paper_comparison.md"].read_text()
    assert (
        "<h2>Beside the paper</h2>" in html
        and "Table 9 beside the paper&#x27;s (mixed variables)" in html
    )
    assert html.index("Beside the paper") < html.index("<h2>Figures</h2>")


def test_runs_of_another_robot_have_no_paper_cell(tmp_path):
    rec = SqliteRecorder(tmp_path / "o.db")
    run_id = rec.start_run(
        {"method": "ours", "objective": "torque", "seed": 0, "design_names": ["a", "b"]}
    )
    rec.record_evaluations(
        run_id,
        outer=0,
        inner=0,
        designs=np.array([[0.7, 0.8]]),
        kind="real",
        interactions=1,
        seconds=0.1,
        costs=[{"torque": 1.0}],
    )
    rec.finish(
        run_id,
        {"best_design": [0.7, 0.8], "best_cost": 1.0, "nominal_cost": 2.0, "improvement": 0.5},
    )
    files = write_report(rec.store, None, tmp_path / "rep", sim2sim=False)
    assert read_csv(files["paper_table6.csv"]) == [] and read_csv(files["paper_table9.csv"]) == []
    md = files["paper_comparison.md"].read_text()
    assert "No run of this report has a cell in this table of the paper." in md
    assert "45 of 45 (Table 6)" in md


def test_table7_ratios_are_paired_per_cell_with_their_standard_error(tmp_path):
    """Each run against the paper's method's run of the same objective, terrain and seed: a
    run without a partner is left out, a ratio that straddles 1 within 2 SE is no verdict."""
    rec = SqliteRecorder(tmp_path / "p.db")
    # ours: 1000 training + 400 evaluation interactions, 1 s + 4 x 0.5 s at every seed
    for s in range(3):
        _record(rec, "ours", s, [0.5, 0.55], 0.4, steps=1000, evals=4)
    # no-surrogate: evaluation 8, 10, 12 designs x 100 (ratios 1800/1400, 2000/1400, 2200/1400; time
    # 5/3, 6/3, 7/3); seed 5 has no ours to pair with and must not count
    for s, evals in ((0, 8), (1, 10), (2, 12), (5, 40)):
        _record(rec, "no-surrogate", s, [1.2, 0.6], 0.3, steps=1000, evals=evals)
    # no-real on another terrain: no cell shared with ours
    _record(rec, "no-real", 0, [1.0, 1.0], 0.0, terrain="slope")
    # BO: training 1400 at seed 0, 1000 at seed 1 and 1800 at seed 2, no evaluation rows:
    # interaction ratios 1.0, 0.714, 1.286 -> mean 1.0 (within 2 SE of equal)
    for s, steps in ((0, 1400), (1, 1000), (2, 1800)):
        _record(rec, "bo-specialized", s, [0.5, 0.5], 0.3, optimizer="bo", steps=steps, evals=0)
    files = write_report(rec.store, None, tmp_path / "rep", sim2sim=False)
    t7 = {r["method"]: r for r in read_csv(files["paper_table7.csv"])}
    nos = t7["no-surrogate"]
    ratios = np.array([1800, 2000, 2200]) / 1400
    assert int(nos["pairs"]) == 3 and int(nos["runs"]) == 4
    assert float(nos["interactions_ratio"]) == pytest.approx(ratios.mean())
    assert float(nos["interactions_ratio_se"]) == pytest.approx(ratios.std(ddof=1) / math.sqrt(3))
    assert float(nos["evaluation_ratio"]) == pytest.approx(2.5)  # 800/400, 1000/400, 1200/400
    assert float(nos["time_ratio"]) == pytest.approx(2.0) and float(
        nos["time_ratio_se"]
    ) == pytest.approx(1 / 3 / math.sqrt(3))
    assert nos["interactions_verdict"] == "costlier as in the paper"
    assert t7["no-real"]["pairs"] == "0" and t7["no-real"]["interactions_verdict"].startswith("n/a")
    bo = t7["bo-specialized"]
    assert float(bo["interactions_ratio"]) == pytest.approx(1.0)
    assert bo["interactions_verdict"] == "within 2 SE of equal, the paper's is costlier"
    assert (
        t7["ours"]["interactions_verdict"] == "reference"
        and float(t7["ours"]["interactions_ratio"]) == 1.0
    )
    md = files["paper_comparison.md"].read_text()
    assert (
        f"| Ours w/o Surrogate | pso | 4 | 3 | {ratios.mean():.2f} "
        f"± {ratios.std(ddof=1) / math.sqrt(3):.2f}, 1.29 |" in md
    )


def test_table7_wall_clock_pairs_only_runs_of_the_same_code(tmp_path):
    """Interactions pair every run with ours' of its cell; the wall clock only runs made by the
    same clean commit: another commit's ours, or a modified tree, is no partner for it."""
    rec = SqliteRecorder(tmp_path / "w.db")
    for s in range(3):  # ours: 1 s + 4 x 0.5 s; seed 2 by other code
        _record(rec, "ours", s, [0.5, 0.55], 0.4, evals=4, commit="c0ffee" if s < 2 else "0ld")
    for s, evals, commit in (
        (0, 8, "c0ffee"),
        (1, 10, "c0ffee"),
        (2, 12, "c0ffee"),
    ):  # time 5/3, 6/3 (7/3 unpaired)
        _record(rec, "no-surrogate", s, [1.2, 0.6], 0.3, evals=evals, commit=commit)
    for s, commit in ((0, "c0ffee+dirty"), (1, None)):  # unknown code: interactions only
        _record(rec, "no-retrain", s, [1.0, 1.0], 0.1, evals=4, commit=commit)
    files = write_report(rec.store, None, tmp_path / "rep", sim2sim=False)
    t7 = {r["method"]: r for r in read_csv(files["paper_table7.csv"])}
    nos, ret = t7["no-surrogate"], t7["no-retrain"]
    assert (nos["pairs"], nos["time_pairs"]) == ("3", "2")
    assert float(nos["interactions_ratio"]) == pytest.approx(np.mean([1800, 2000, 2200]) / 1400)
    assert float(nos["time_ratio"]) == pytest.approx(5.5 / 3) and float(
        nos["time_ratio_se"]
    ) == pytest.approx(1 / 6)
    assert (ret["pairs"], ret["time_pairs"], ret["time_ratio"]) == ("2", "0", "")
    assert float(ret["interactions_ratio"]) == pytest.approx(1.0)
    assert ret["time_verdict"] == "n/a (no pair made by the same code)"
    md = files["paper_comparison.md"].read_text()
    assert "| Ours w/o Surrogate | pso | 3 | 3 |" in md and "same clean git commit" in md


def test_table7_wall_clock_at_equal_machine_speed(tmp_path):
    """A run made while the machine was twice as slow takes twice the wall clock; divided by
    its own seconds per training interaction it costs what it would have cost at full speed."""
    rec = SqliteRecorder(tmp_path / "s.db")
    for s in range(2):  # ours: 1000 training interactions in 1 s + 4 x 0.5 s
        _record(rec, "ours", s, [0.5, 0.55], 0.4, steps=1000, evals=4)
    for s, slow in ((0, 2.0), (1, 3.0)):  # the same work on a machine 2 and 3 times slower
        _record(rec, "no-surrogate", s, [1.2, 0.6], 0.3, steps=1000, evals=4, slow=slow)
    for s in range(2):  # BO's training: 2000 interactions at full speed, no evaluation rows
        _record(rec, "bo-specialized", s, [0.5, 0.5], 0.3, optimizer="bo", steps=2000, evals=0)
    _record(
        rec, "no-retrain", 0, [1.0, 1.0], 0.1, steps=0, evals=4
    )  # no training: no speed to measure
    files = write_report(rec.store, None, tmp_path / "rep", sim2sim=False)
    t7 = {r["method"]: r for r in read_csv(files["paper_table7.csv"])}
    nos, bo, ret = t7["no-surrogate"], t7["bo-specialized"], t7["no-retrain"]
    assert float(nos["time_ratio"]) == pytest.approx(2.5)  # 6/3 and 9/3
    assert float(nos["speed_time_ratio"]) == pytest.approx(1.0) and float(
        nos["speed_time_ratio_se"]
    ) == pytest.approx(0.0)
    assert nos["speed_time_verdict"] == "within 2 SE of equal, the paper's is costlier"
    # BO: 1 s per 2000 interactions is twice ours' speed per interaction: 1 s of wall at 2000 / s
    # against 3 s at 1000 / s: 2000 against 3000 interaction-equivalents
    assert float(bo["time_ratio"]) == pytest.approx(1 / 3) and float(
        bo["speed_time_ratio"]
    ) == pytest.approx(2 / 3)
    assert ret["speed_time_ratio"] == "" and ret["speed_time_verdict"].startswith(
        "n/a (no training"
    )
    assert "| Ours w/o Surrogate | pso | 2 | 2 |" in files["paper_comparison.md"].read_text()


def test_the_figure_beside_the_paper_draws_each_cell_with_its_error_bar(compared):
    from coadapt_core.analysis.paper_figure import bars_of

    _, files = compared
    assert files["paper_table6.png"].stat().st_size > 1000
    assert "![Table 6 beside the paper's" in files["paper_comparison.md"].read_text()
    rows = {r["method"]: r for r in read_csv(files["paper_table6.csv"])}
    typed = [
        {
            k: (
                float(v)
                if k in ("improvement", "improvement_se", "paper_improvement") and v
                else v or None
            )
            for k, v in r.items()
        }
        for r in rows.values()
    ]
    (flat,) = bars_of(typed).values()
    ours = next(b for b in flat if b["method"] == "ours")
    # no common-scenario rows in this store: the runs' own improvement, marked as such
    assert (
        ours["common"] is False
        and ours["value"] == pytest.approx(45.0)
        and ours["paper"] == pytest.approx(45.9)
    )
    assert ours["se"] == pytest.approx(100 * 0.05 / math.sqrt(3))
    with_common = dict(typed[0], common_improvement=0.2, common_improvement_se=0.01)
    (bar,) = next(iter(bars_of([with_common]).values()))
    assert (
        bar["common"] is True
        and bar["value"] == pytest.approx(20.0)
        and bar["se"] == pytest.approx(1.0)
    )
