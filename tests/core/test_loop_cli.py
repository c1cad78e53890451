"""`coadapt run` and its config: presets, YAML, precedence, validation with exit code 2,
the --json line, --resume; the learner is replaced by the analytic backend."""

from __future__ import annotations

import json

import numpy as np
import pytest

import coadapt_core.coadapt.setup as loop_setup
from coadapt_core.cli import main
from coadapt_core.coadapt.config import PRESETS
from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.summary import JSON_PLAIN_AND_FALLS as PLAIN_AND_FALLS
from coadapt_core.errors import UserError
from tests.fakes.analytic import AnalyticBackend, optimum_of


@pytest.fixture
def fake_learner(monkeypatch):
    monkeypatch.setattr(
        loop_setup, "universal_policy_factory", lambda *a, **k: lambda seed: AnalyticBackend(seed)
    )


def test_paper_preset_has_section_4_1_3_settings():
    c = make_config("paper")
    assert (c.outer_iterations, c.population, c.optimizer_iterations, c.agents_per_design) == (
        3,
        100,
        5,
        50,
    )
    assert c.surrogate_probability == 0.5
    assert (
        c.optimizer_options == {}
    )  # pso's declared defaults are the paper's: inertia 0.9, c1 = c2 = 2
    from coadapt_core.plugins import get_registry

    defaults = {s.name: s.default for s in get_registry().get("optimizer", "pso").option_specs}
    assert (defaults["inertia"], defaults["c1"], defaults["c2"]) == (0.9, 2.0, 2.0)


def test_cli_beats_yaml_beats_preset(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("population: 7\nseed: 5\nobjective: [power, torque]\noptimizer: nsga2\n")
    c = make_config("smoke", path, {"seed": 11, "population": None})
    assert c.population == 7 and c.seed == 11 and c.objective == "power,torque"
    assert c.outer_iterations == PRESETS["smoke"]["outer_iterations"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["--surrogate-probability", "1.7"],
            "surrogate_probability must be a probability in [0, 1]",
        ),
        (
            ["--evaluation-probability", "1.7"],
            "surrogate_probability must be a probability in [0, 1]",
        ),  # its earlier name
        (["--population", "0"], "population must be an integer >= 1"),
        (["--design-ranges", "1.5:0.5,0.5:1.5"], "inverted bounds"),
        (["--design-ranges", "0.2:1.5,0.5:1.5"], "leaves its bounds"),
        (["--method", "magic"], "method 'magic' is not one of"),
        (["--terrain", "ice"], "terrain 'ice'"),
        (["--optimizer", "cmaes"], "unknown optimizer 'cmaes'"),
        (["--objective", "speed"], "unknown objective 'speed'"),
        (["--objective", "power,torque"], "need a multi-objective optimizer"),
        (["--optimizer", "nsga2"], "needs 2-3 objectives"),
        (["--preset", "huge"], "preset 'huge'"),
        (["--narrow-min-width", "0"], "narrow_min_width"),
        (
            ["--specialized-init", "warm"],
            "specialized_init 'warm' is not one of scratch, universal",
        ),
        (
            ["--objective", "composite", "--objective-weights", "speed=1"],
            "unknown component 'speed'",
        ),
        (["--resume", "no-such-run"], "no run 'no-such-run'"),
    ],
)
def test_bad_values_are_one_line_and_exit_2(tmp_path, capsys, fake_learner, args, message):
    code = main(["run", "--preset", "smoke", "--out", str(tmp_path), *args])
    err = capsys.readouterr().err
    assert code == 2
    assert message in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_bad_yaml_is_exit_2(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text("population: [1, 2\n")
    assert main(["run", "--config", str(path)]) == 2
    path.write_text("populaton: 3\n")
    assert main(["run", "--config", str(path)]) == 2
    assert "unknown config file key 'populaton'" in capsys.readouterr().err


def test_run_json_last_line_and_resume(tmp_path, capsys, fake_learner):
    args = [
        "run",
        "--optimizer",
        "pso",
        "--sim",
        "mujoco",
        "--objective",
        "torque",
        "--preset",
        "smoke",
        "--population",
        "12",
        "--optimizer-iterations",
        "4",
        "--agents-per-design",
        "30",
        "--out",
        str(tmp_path),
        "--json",
    ]
    assert main(args) == 0
    line = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert {
        "run_id",
        "best_design",
        "best_cost",
        "best_cost_se",
        "nominal_cost",
        "nominal_cost_se",
        "improvement",
        "improvement_se",
        "significant",
        "best_fall_rate",
        "nominal_fall_rate",
        *PLAIN_AND_FALLS,
        "interactions",
        "seconds",
        "reliable",
        "reliability",
    } <= set(line)
    assert line["reliable"] is None  # the analytic fake measures no walking: not marked either way
    assert np.abs(np.array(line["best_design"]) - optimum_of("torque")).max() < 0.15
    assert line["improvement"] > 0.15 and line["interactions"] > 0
    # resuming a finished run by id prints the same result
    assert main(["run", "--resume", line["run_id"], "--out", str(tmp_path), "--json"]) == 0
    again = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert again["best_design"] == line["best_design"]


def test_resume_with_store_writes_there_from_any_folder(
    tmp_path, capsys, fake_learner, monkeypatch
):
    """A run started with a relative --store from one folder, resumed from another with
    --store: the rows go to the store named now (the recorded relative path would miss)."""
    from coadapt_core.results import ResultsStore
    from coadapt_core.results.recorders import read_evaluations

    first, second = tmp_path / "a", tmp_path / "b"
    first.mkdir()
    second.mkdir()
    monkeypatch.chdir(first)
    args = ["run", "--preset", "smoke", "--objective", "torque", "--population", "6"]
    assert main([*args, "--store", "runs/s.db", "--out", "runs", "--no-video", "--json"]) == 0
    line = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    run_dir = first / "runs" / line["run_id"]
    monkeypatch.chdir(second)
    other = second / "other.db"
    code = main(["run", "--resume", str(run_dir), "--store", str(other), "--no-video", "--json"])
    assert code == 0, capsys.readouterr().err
    again = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert again["best_design"] == line["best_design"]
    with ResultsStore(other) as store:  # the run and every row, refilled from its folder
        assert store.get_run(line["run_id"])["status"] == "finished"
        assert store.count_evaluations(line["run_id"]) == len(read_evaluations(run_dir)) > 0
    assert not (second / "runs").exists()  # nothing made from the recorded relative path


def test_run_table_output_and_mixed_pso_uses_motor_types(tmp_path, capsys, fake_learner):
    assert (
        main(
            [
                "run",
                "--optimizer",
                "mixed-pso",
                "--preset",
                "smoke",
                "--population",
                "8",
                "--out",
                str(tmp_path),
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "hip_motor" in out and "improvement over nominal" in out and "run folder:" in out


def test_nsga2_front_is_non_dominated_and_printed_stored_plotted_alike(
    tmp_path, capsys, fake_learner
):
    from coadapt_core.analysis.facts import run_facts
    from coadapt_core.analysis.pareto_figure import pareto_points
    from coadapt_core.cli.run_summary import with_se
    from coadapt_core.pareto import is_dominated
    from coadapt_core.results import ResultsStore

    db = tmp_path / "s.db"
    assert (
        main(
            [
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
                "--out",
                str(tmp_path),
                "--store",
                str(db),
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    printed = [
        line.strip() for line in out.split("Pareto front", 1)[1].splitlines()[1:] if "->" in line
    ]
    store = ResultsStore(db)
    (run,) = store.list_runs()
    stored = run["summary"]["pareto_front"]
    costs = np.array([[c["power"], c["torque"]] for c in stored["costs"]])  # [F, 2]
    assert len(costs) >= 2
    # no design of the front is dominated by another design of the front
    for i, point in enumerate(costs):
        assert not is_dominated(point, np.delete(costs, i, axis=0)), point
    # printed == stored (the printed text is the stored numbers: index, design, costs +- SE,
    # the returned design marked)
    ses = stored.get("costs_se") or [{}] * len(costs)
    expected = [
        f"{j}: "
        + ", ".join(f"{x:.3f}" for x in d)
        + " -> "
        + ", ".join(f"{k} {with_se(v, s.get(k))}" for k, v in c.items())
        + (" <- returned" if j == 0 else "")
        for j, (d, c, s) in enumerate(zip(stored["designs"], stored["costs"], ses, strict=True))
    ]
    assert [" ".join(p.split()) for p in printed] == [" ".join(e.split()) for e in expected]
    # plotted == stored, and Table 6's design (lowest first cost) lies on it
    plotted = pareto_points(run_facts(store, run))
    np.testing.assert_allclose(plotted["front"], costs[np.lexsort(costs.T[::-1])])
    best = run["summary"]["best_costs"]
    assert [best["power"], best["torque"]] in costs.tolist()
    assert best["power"] == costs[:, 0].min()


def test_config_validation_names_field():
    with pytest.raises(UserError) as info:
        make_config("smoke", overrides={"agents_per_design": -3})
    assert info.value.field == "agents_per_design"


def test_composite_objective_with_weights_through_cli(tmp_path, capsys, fake_learner):
    args = [
        "run",
        "--objective",
        "composite",
        "--objective-weights",
        "tracking=1,torque=0.5",
        "--preset",
        "smoke",
        "--population",
        "12",
        "--optimizer-iterations",
        "4",
        "--agents-per-design",
        "30",
        "--out",
        str(tmp_path),
        "--json",
    ]
    assert main(args) == 0
    line = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert np.abs(np.array(line["best_design"]) - optimum_of("composite")).max() < 0.15


@pytest.mark.slow
def test_real_learner_end_to_end_on_mujoco(tmp_path, capsys):
    """The whole loop on the real universal-policy backend and MuJoCo, at a tiny size: it
    trains twice, evaluates, narrows and reports finite real costs with exact accounting."""
    args = [
        "run",
        "--optimizer",
        "pso",
        "--sim",
        "mujoco",
        "--objective",
        "torque",
        "--preset",
        "smoke",
        "--population",
        "3",
        "--agents-per-design",
        "2",
        "--eval-steps",
        "10",
        "--train-steps",
        "100",
        "--retrain-steps",
        "50",
        "--checkpoint",
        "none",
        "--store",
        "none",
        "--out",
        str(tmp_path),
        "--json",
    ]
    assert main(args) == 0
    line = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert (
        np.isfinite(line["best_cost"])
        and np.isfinite(line["nominal_cost"])
        and line["best_cost"] > 0
    )
    summary = json.loads((tmp_path / line["run_id"] / "summary.json").read_text())
    assert summary["real_evaluations"] + summary["surrogate_evaluations"] == 2 * 2
    # every real round, and the nominal design once per policy (the capped cost rule's
    # reference level)
    assert (
        summary["eval_interactions"]
        == summary["real_evaluations"] * 3 * 2 * 10 + len(summary["spaces"]) * 2 * 10
    )
    assert summary["train_interactions"] > 0 and len(summary["spaces"]) == 2
    assert (tmp_path / line["run_id"] / "checkpoints" / "backend-outer1.pt").is_file()
