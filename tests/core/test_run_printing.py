"""What `coadapt run` prints (issue 43): every cost says its protocol, improvements and fall
differences read in one direction, the table keeps every column in a pipe or a file, the
smoke preset says only that it is too short to judge, and the warnings a researcher needs
(best design at a bound, plain mean not significant, weak surrogate, nominal best not
significant) fire on planted summaries and stay quiet otherwise."""

from __future__ import annotations

import copy
import json
import re
import subprocess
import sys

import numpy as np
import pytest

from coadapt_core.cli.run_summary import better_by, falls_more_by, print_summary
from coadapt_core.coadapt.cautions import (
    at_bound,
    plain_mean_not_significant,
    run_warnings,
    weak_surrogate,
)
from coadapt_core.coadapt.final_check import final_check
from coadapt_core.costs import CostRule
from tests.core.test_cost_rule import Cost, _with_falls

SPACE = {
    "variables": [
        {"name": "thigh_scale", "type": "continuous", "low": 0.5, "high": 1.5},
        {"name": "shank_scale", "type": "continuous", "low": 0.5, "high": 1.5},
    ]
}


def planted(**changes) -> dict:
    """A finished power run's summary: best (0.8, 1.2) 10 +- 1.5 % better, plain mean 9 +- 2 %
    better, a surrogate of pooled Spearman 0.8 over 4 of 6 real rounds; nothing to warn about."""
    rounds = [{"eligible": True, "objectives": {"power": {"spearman": rho}}} for rho in (0.9, 0.7)]
    summary = {
        "run_id": "r1",
        "preset": "quick",
        "best_design": [0.8, 1.2],
        "nominal_design": [1.0, 1.0],
        "spaces": [SPACE],
        "final_space": SPACE,
        "best_costs": {"power": 450.0},
        "nominal_costs": {"power": 500.0},
        "best_costs_se": {"power": 9.0},
        "nominal_costs_se": {"power": 10.0},
        "improvement": 0.10,
        "improvement_se": 0.015,
        "improvements": {"power": 0.10},
        "improvements_se": {"power": 0.015},
        "improvement_plain": 0.09,
        "improvement_plain_se": 0.02,
        "improvements_plain": {"power": 0.09},
        "improvements_plain_se": {"power": 0.02},
        "best_plain_means": {"power": 455.0},
        "best_plain_means_se": {"power": 9.0},
        "nominal_plain_means": {"power": 500.0},
        "nominal_plain_means_se": {"power": 10.0},
        "significant": True,
        "best_is_nominal": False,
        "cost_rule": "capped",
        "cost_units": {"power": "W"},
        "eval_steps": 250,
        "final_scenarios": 64,
        "final_blocks": 2,
        "best_fall_rate": 0.01,
        "best_fall_rate_se": 0.005,
        "nominal_fall_rate": 0.0,
        "nominal_fall_rate_se": 0.0,
        "fall_rate_difference": 0.008,
        "fall_rate_difference_se": 0.004,
        "reliable": True,
        "reliability": "passed the walking gate",
        "interactions": 1000,
        "train_interactions": 600,
        "eval_interactions": 300,
        "final_interactions": 100,
        "real_evaluations": 6,
        "surrogate_evaluations": 4,
        "seconds": 100.0,
        "surrogate_quality": {
            "pooled": {"spearman": 0.8, "rounds": 4},
            "by_objective": {"power": {}},
            "rounds": rounds,
        },
    }
    summary.update(changes)
    return summary


def printed(capsys, summary: dict) -> str:
    print_summary(summary, ["thigh_scale", "shank_scale"])
    return capsys.readouterr().out


# -- the warnings ------------------------------------------------------------------------------
def test_no_warning_on_a_clean_run(capsys):
    assert run_warnings(planted()) == []
    assert "warning" not in printed(capsys, planted())


@pytest.mark.parametrize(
    ("design", "expected"),
    [
        (
            [0.54, 1.2],
            "thigh_scale 0.540 at its lower bound 0.5",
        ),  # the 0.50-0.54: 4 % of the range
        ([0.8, 1.46], "shank_scale 1.460 at its upper bound 1.5"),
        ([0.56, 1.44], None),  # 6 % of the range from either bound: inside
    ],
)
def test_a_best_design_at_a_bound_is_said(design, expected):
    warning = at_bound(planted(best_design=design))
    if expected is None:
        assert warning is None
    else:
        assert expected in warning and "bound of the design space" in warning
    # the bound is the run's first space's, not the narrowed one's
    narrowed = {"variables": [{**v, "low": 0.54, "high": 0.9} for v in SPACE["variables"]]}
    assert (
        at_bound(planted(best_design=[0.7, 0.7], final_space=narrowed, spaces=[SPACE, narrowed]))
        is None
    )


def test_a_significant_gain_whose_plain_mean_is_not_is_said(capsys):
    # the power run: +8.8 +- 1.8 % under the rule, plain mean -0.6 +- 10.1 %
    summary = planted(
        improvement=0.088,
        improvement_se=0.018,
        improvement_plain=-0.006,
        improvement_plain_se=0.101,
    )
    warning = plain_mean_not_significant(summary)
    assert warning.startswith("power: the improvement (+8.8 +- 1.8 %, capped cost) is significant")
    assert (
        "(-0.6 +- 10.1 %) is not (under 4 paired standard errors or of the other sign)" in warning
    )
    assert warning in " ".join(printed(capsys, summary).split())
    # a plain mean of 9 +- 2 % is 4.5 SE: quiet; so is a gain that is not significant itself
    assert plain_mean_not_significant(planted()) is None
    assert plain_mean_not_significant({**summary, "significant": False}) is None


def test_a_weak_surrogate_is_said_with_the_rounds_it_covers():
    rounds = [{"eligible": True, "objectives": {"power": {"spearman": r}}} for r in (0.6, 0.14)]
    quality = {
        "pooled": {"spearman": 0.45, "rounds": 2},
        "by_objective": {"power": {}},
        "rounds": rounds,
    }
    warning = weak_surrogate(planted(surrogate_quality=quality, real_evaluations=8))
    assert warning.startswith(
        "surrogate: pooled Spearman 0.45 over 2 judged real rounds of 8, last judged round 0.14"
    )
    assert "not comparable with runs judged on every round" in warning
    every = {**quality, "pooled": {"spearman": 0.45, "rounds": 8}}
    assert "not comparable" not in weak_surrogate(
        planted(surrogate_quality=every, real_evaluations=8)
    )
    assert weak_surrogate(planted()) is None  # 0.8
    assert (
        weak_surrogate(planted(surrogate_quality={"pooled": {"spearman": None, "rounds": 0}}))
        is None
    )


def test_the_surrogate_s_pooled_figure_is_printed_with_the_rounds_it_covers(capsys):
    out = " ".join(printed(capsys, planted()).split())
    assert (
        "surrogate (in-run rounds): pooled Spearman 0.80 over 4 judged real rounds of 6 (only "
        "rounds a fit "
        "already covers are judged; --surrogate-error-fits judges every one)"
    ) in out
    weak = planted(surrogate_quality={"pooled": {"spearman": 0.3, "rounds": 6}, "rounds": []})
    out = " ".join(printed(capsys, weak).split())
    assert "surrogate (in-run rounds)" not in out  # said once, as the warning
    assert (
        "warning: surrogate: pooled Spearman 0.30 over 6 judged real rounds of 6 is below 0.5"
        in out
    )
    assert "not comparable with runs judged" not in out


def test_a_nominal_best_is_not_significant():
    """Every candidate falls more: the nominal design stands, 0.0 +- 0.0 % and not significant
    (it was `significant: true`); a real gain still is."""
    designs = np.array([[0.5, 0.5], [0.7, 0.7], [1.0, 1.0]])
    check = final_check(
        _with_falls([0.10, 0.08], [0.4, 0.3]),
        designs,
        [Cost()],
        max_blocks=2,
        min_blocks=2,
        rule=CostRule("capped"),
        fall_tolerance=0.01,
    )
    summary = check.uncertainty(["cost"])
    assert check.best == 2 and summary["best_is_nominal"] is True
    assert summary["improvement_se"] == 0.0 and summary["significant"] is False
    gain = final_check(
        _with_falls([0.0, 0.0], [0.3, 0.1]),
        designs,
        [Cost()],
        max_blocks=2,
        min_blocks=2,
        rule=CostRule("capped"),
        fall_tolerance=0.01,
    )
    assert gain.best == 0 and gain.significant is True


# -- one direction, one protocol per number ----------------------------------------------------
def test_improvements_and_fall_differences_read_in_one_direction(capsys):
    assert better_by(0.284, 0.05) == "better by 28.4 +- 5.0 %"
    assert better_by(-0.031) == "worse by 3.1 %"
    assert falls_more_by(0.008, 0.004) == "falls more by 0.8 +- 0.4 points than nominal"
    assert falls_more_by(-0.02, 0.01) == "falls less by 2.0 +- 1.0 points than nominal"
    out = " ".join(printed(capsys, planted()).split())
    assert (
        "improvement over nominal (final check): power better by 10.0 +- 1.5 % (plain mean: power "
        "better by "
        "9.0 +- 2.0 %); best falls more by 0.8 +- 0.4 points than nominal"
    ) in out
    assert "+10.0" not in out and "+0.8" not in out


def test_the_landscape_line_reads_in_the_same_direction():
    from coadapt_core.cli.landscape import landscape_line

    line = landscape_line(
        {
            "run_id": "l1",
            "best_design": [0.6, 1.2],
            "best_cost": 100.0,
            "best_cost_se": 3.0,
            "nominal_cost": 120.0,
            "nominal_cost_se": 4.0,
            "improvement": 0.1667,
            "improvement_se": 0.02,
            "improvement_plain": -0.01,
            "improvement_plain_se": 0.05,
            "best_plain_mean": 101.0,
            "nominal_plain_mean": 100.0,
        },
        8,
        100,
        "W",
    )
    assert (
        "improvement: better by 16.7 +- 2.0 %" in line
        and "improvement: worse by 1.0 +- 5.0 %" in line
    )
    assert "the landscape's protocol" in line


def test_a_smoke_run_says_only_that_it_is_too_short_to_judge(capsys):
    reason = (
        "not judged: 20 steps per scenario are too short; measured: the policy does not walk (...)"
    )
    out = " ".join(
        printed(
            capsys, planted(preset="smoke", eval_steps=20, reliable=None, reliability=reason)
        ).split()
    )
    assert "walking gate: too short to judge (smoke preset, 20 steps per scenario" in out
    assert "walk (" not in out and "does not walk" not in out
    assert (
        "improvement over nominal (final check; smoke preset, too short to judge: a check that "
        "the run is wired, "
        "not a result)" in out
    )
    # a run trained from scratch at the smoke preset too: its summary keeps reliable false
    out = " ".join(
        printed(
            capsys, planted(preset="smoke", reliable=False, reliability="trained from scratch")
        ).split()
    )
    assert "UNRELIABLE" not in out and "too short to judge" in out


# -- a real NSGA-II smoke run, piped into files ------------------------------------------------
@pytest.fixture(scope="module")
def piped_run(tmp_path_factory) -> dict:
    """`coadapt run --optimizer nsga2 --objective power,torque --preset smoke` with stdout and
    stderr redirected to files (not a terminal), as `tee` or a log file gets it."""
    tmp = tmp_path_factory.mktemp("piped")
    out, err = tmp / "out.txt", tmp / "err.txt"
    env = {"COADAPT_PROGRESS_EVERY": "0.5", "PATH": "/usr/bin:/bin", "HOME": str(tmp)}
    with open(out, "w") as fo, open(err, "w") as fe:
        code = subprocess.run(
            [
                sys.executable,
                "-m",
                "coadapt_core",
                "run",
                "--optimizer",
                "nsga2",
                "--objective",
                "power,torque",
                "--preset",
                "smoke",
                "--out",
                str(tmp / "runs"),
                "--store",
                "none",
                "--no-video",
            ],
            stdout=fo,
            stderr=fe,
            env=env,
            cwd=tmp,
            timeout=600,
        ).returncode
    (run_dir,) = (tmp / "runs").iterdir()
    return {
        "code": code,
        "out": out.read_text(),
        "err": err.read_text(),
        "summary": json.loads((run_dir / "summary.json").read_text()),
    }


@pytest.mark.slow
def test_a_piped_nsga2_table_keeps_every_column(piped_run):
    assert piped_run["code"] == 0, piped_run["err"][-2000:]
    lines = piped_run["out"].splitlines()
    top = next(
        i for i, line in enumerate(lines) if "coadapt run" in line and "final check costs" in line
    )
    header = " ".join(lines[top + 1 : top + 5])
    for column in (
        "thigh_scale",
        "shank_scale",
        "power [W]",
        "torque [(Nm)^2]",
        "power plain",
        "torque plain",
        "fall rate",
    ):
        assert column in header, (column, header)
    assert header.count("+- SE") == 5 and header.count("mean +- SE") == 2
    summary = piped_run["summary"]
    number = r"-?[\d.]+"
    cost = rf"{number} \+- {number}"
    for row, design in (("best", summary["best_design"]), ("nominal", summary["nominal_design"])):
        (line,) = [
            x for x in lines if x.split()[:1] == [row]
        ]  # each row on one line, no cell folded
        cells = re.split(r"\s{2,}", line.strip())
        assert cells[0] == row and [float(c) for c in cells[1:3]] == pytest.approx(design, abs=5e-4)
        assert all(re.fullmatch(cost, c) for c in cells[3:7]), cells
        assert re.fullmatch(rf"{cost} %", cells[7]), cells
    assert max(len(x) for x in lines) > 80  # wider than a terminal's 80 columns, not cut to it


@pytest.mark.slow
def test_every_printed_cost_of_a_run_carries_its_protocol(piped_run):
    err = piped_run["err"].splitlines()
    progress = [line for line in err if line.startswith("run ") and "best" in line]
    assert len(progress) >= 2 and all("in-run best" in line for line in progress)
    assert re.search(r"in-run best \d", progress[-1])
    out = piped_run["out"]
    flat = " ".join(out.split())
    assert "final check costs" in out.splitlines()[0] + out.splitlines()[1]
    assert "costs: per step over the final check's" in flat
    assert re.search(r"improvement over nominal \(final check[;)]", flat)
    assert re.search(r"Pareto front \(\d+ designs?, final check costs", flat)
    # every number with a unit of cost on stdout lies in one of those labelled places
    assert "real costs" not in flat and " +" not in flat.replace(" +- ", " ")


@pytest.mark.slow
def test_a_run_names_the_numerics_it_trained_and_evaluated_with(piped_run):
    """summary.json (and so the store's row) records the learner's precision in force ("auto"
    resolved on this CPU), the CPU's model, torch's and MuJoCo's versions; the run's last
    lines say them (issue 61)."""
    import importlib.metadata

    from coadapt_core.learning.config import resolve_precision
    from coadapt_core.numerics import numerics_text, processor_name

    numerics = piped_run["summary"]["numerics"]
    expected = resolve_precision("auto", "cpu")
    assert numerics["precision"] == numerics["pseudo_precision"] == expected
    assert numerics["rollout_precision"] == "float32" and numerics["device"] == "cpu"
    assert numerics["processor"] == processor_name()
    assert numerics["torch"] == importlib.metadata.version("torch")
    assert (numerics["engine"], numerics["engine_version"]) == (
        "mujoco",
        importlib.metadata.version("mujoco"),
    )
    flat = " ".join(piped_run["out"].split())
    assert f"numerics: {numerics_text(numerics)}" in flat
    assert f"numerics: {expected} learner" in flat


def test_the_summary_records_the_warnings_and_the_json_line_carries_them(
    tmp_path, capsys, monkeypatch
):
    import coadapt_core.coadapt.setup as loop_setup
    from coadapt_core.cli import main
    from tests.fakes.analytic import AnalyticBackend

    monkeypatch.setattr(
        loop_setup, "universal_policy_factory", lambda *a, **k: lambda seed: AnalyticBackend(seed)
    )
    # a range whose lower bound the analytic optimum (thigh 0.6) lies below: the best sits at it
    assert (
        main(
            [
                "run",
                "--optimizer",
                "pso",
                "--objective",
                "torque",
                "--preset",
                "smoke",
                "--population",
                "8",
                "--design-ranges",
                "0.9:1.5,0.5:1.5",
                "--out",
                str(tmp_path),
                "--store",
                "none",
                "--no-video",
                "--json",
            ]
        )
        == 0
    )
    line = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    (run_dir,) = tmp_path.iterdir()
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["warnings"] == line["warnings"] == run_warnings(copy.deepcopy(summary))
    assert any("thigh_scale" in w and "lower bound 0.9" in w for w in line["warnings"]), line[
        "warnings"
    ]


# -- the first run explains itself (issue 50) ----------------------------------------------------
def test_a_quick_run_ends_saying_what_the_preset_is_for_after_its_warnings(capsys):
    out = " ".join(printed(capsys, planted(preset="quick", best_design=[0.52, 1.2])).split())
    warned = out.index("warning: best design at a bound")
    note = out.index("quick preset: a first answer in minutes")
    assert warned < note and out.count("warning:") == 1
    assert (
        "the warning above says where it is thin (guidance, not a failure). For a firmer "
        "answer: more seeds (--seed 1, --seed 2, or `coadapt grid`), then `--preset paper`"
    ) in out
    clean = " ".join(printed(capsys, planted(preset="quick")).split())
    assert (
        "quick preset: a first answer in minutes" in clean
        and "nothing flagged at this size" in clean
    )
    assert "quick preset" not in printed(capsys, planted(preset="paper"))
