"""`coadapt verify` on real MuJoCo (issue 60): the specialists start from the run's universal
weights, the best's and the nominal's get the same budget, seeds and scenarios, a cut
verification continues from its last state and ends as an uncut one, the command works on a
smoke run and a two-objective run (`--pick`), its rows reach the store, and bad input is one
line, exit 2, nothing created."""

from __future__ import annotations

import csv
import dataclasses
import json
import shutil

import numpy as np
import pytest
import torch

from coadapt_core.cli import main
from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.run import run_coadaptation
from coadapt_core.coadapt.state import load_state, save_state
from coadapt_core.coadapt.verify import (
    VERIFY_SEED,
    default_factories,
    plan_verification,
    seed_at,
    verdict,
    verify,
)
from coadapt_core.learning.checkpoints import read_checkpoint
from coadapt_core.results.store import ResultsStore

pytestmark = pytest.mark.slow

SMOKE = dict(
    optimizer="pso",
    sim="mujoco",
    objective="torque",
    seed=0,
    eval_steps=12,
    train_steps=240,
    retrain_steps=120,
    final_max_blocks=2,
    final_min_blocks=1,
)


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    base = tmp_path_factory.mktemp("verify")
    config = make_config("smoke", overrides={**SMOKE, "out": str(base / "runs")})
    return run_coadaptation(config, run_dir=base / "runs" / "smoke").run_dir


def actor(state: dict) -> dict[str, torch.Tensor]:
    return {k: v.detach().clone().float() for k, v in state["actor"].items()}


class Spy:
    """The real factories, recording each specialist backend's weights when it is built, its
    training calls and every evaluation call."""

    def __init__(self, plan, cut_train: int | None = None, cut_real: int | None = None):
        self.train_factory, self.eval_factory = default_factories(plan)
        self.built, self.trains, self.reals = [], [], []
        self.cut_train, self.cut_real = cut_train, cut_real

    def factory(self, seed):
        backend = self.train_factory(seed)
        self.built.append(actor(backend.ppo.state_dict()))
        train, real = backend.train, backend.real_fitness

        def traced_train(designs, steps, *, seed=0):
            if self.cut_train is not None and len(self.trains) == self.cut_train:
                raise KeyboardInterrupt("cut")
            self.trains.append((np.asarray(designs).tolist(), int(steps), int(seed)))
            return train(designs, steps, seed=seed)

        def traced_real(designs, objectives, **kw):
            if self.cut_real is not None and len(self.reals) == self.cut_real:
                raise KeyboardInterrupt("cut")
            self.reals.append(("specialist", np.asarray(designs).tolist(), kw))
            return real(designs, objectives, **kw)

        backend.train, backend.real_fitness = traced_train, traced_real
        return backend

    def evaluator(self, seed):
        backend = self.eval_factory(seed)
        real = backend.real_fitness

        def traced_real(designs, objectives, **kw):
            self.reals.append(("universal", np.asarray(designs).tolist(), kw))
            return real(designs, objectives, **kw)

        backend.real_fitness = traced_real
        return backend


def test_specialists_start_from_the_universal_weights_with_equal_budgets_and_scenarios(
    smoke_run, tmp_path
):
    plan = plan_verification(smoke_run, budget=300, chunk=100)
    plan = dataclasses.replace(plan, folder=tmp_path / "v")
    spy = Spy(plan)
    result = verify(plan, factory=spy.factory, eval_factory=spy.evaluator)

    universal = actor(read_checkpoint(plan.universal)["ppo"])
    # the two specialists' backends as built, before any training, hold the universal weights
    first_two = spy.built[:2]
    assert len(first_two) == 2
    for built in first_two:
        assert built.keys() == universal.keys()
        assert all(torch.equal(built[k], universal[k]) for k in universal)
    # ... and end elsewhere: fine-tuned from there, not replaced
    for role in ("best", "nominal"):
        tuned = actor(read_checkpoint(plan.folder / f"checkpoints/specialist-{role}.pt")["ppo"])
        moved = sum(float((tuned[k] - universal[k]).abs().sum()) for k in universal)
        assert moved > 0
    # equal budgets and the same seeds: the same chunks for each design, in two chunks at least
    best, nominal = plan.designs["best"].tolist(), plan.designs["nominal"].tolist()
    half = len(spy.trains) // 2
    assert half >= 2 and len(spy.trains) == 2 * half
    assert [t[0] for t in spy.trains] == [[best]] * half + [[nominal]] * half
    assert [t[1:] for t in spy.trains[:half]] == [t[1:] for t in spy.trains[half:]]
    assert [t[2] for t in spy.trains[:half]] == [
        seed_at(plan.seed, VERIFY_SEED, 1, c) for c in range(half)
    ]
    specs = result["specialists"]
    assert specs["best"]["interactions"] == specs["nominal"]["interactions"] >= 300
    # the same scenarios for every design and policy, block by block
    blocks = result["blocks"]
    assert plan.min_blocks <= blocks <= plan.max_blocks
    by_block = [spy.reals[i * 3 : i * 3 + 3] for i in range(blocks)]
    assert len(spy.reals) == 3 * blocks
    for calls in by_block:
        assert [c[0] for c in calls] == ["specialist", "specialist", "universal"]
        assert [c[1] for c in calls] == [[best], [nominal], [best, nominal]]
        assert len({json.dumps(c[2], sort_keys=True) for c in calls}) == 1
    assert len({c[0][2]["seed"] for c in by_block}) == blocks  # a fresh block each time
    entry = result["designs"][0]
    assert entry["role"] == "best" and entry["verdict"] in (
        "holds",
        "grows",
        "shrinks",
        "does not hold",
    )
    for side in ("specialist", "universal"):
        assert np.isfinite(entry[side]["improvement"]) and entry[side]["improvement_se"] > 0
    assert entry["difference"] == pytest.approx(
        entry["specialist"]["improvement"] - entry["universal"]["improvement"]
    )
    assert entry["difference_se"] > 0
    assert result["scenarios"] == blocks * plan.config.evaluation_agents


def test_a_cut_verification_continues_from_its_last_state_and_ends_as_an_uncut_one(
    smoke_run, tmp_path
):
    plan = plan_verification(smoke_run, budget=300, chunk=100)
    whole = dataclasses.replace(plan, folder=tmp_path / "whole")
    spy = Spy(whole)
    uncut = verify(whole, factory=spy.factory, eval_factory=spy.evaluator)

    cut = dataclasses.replace(plan, folder=tmp_path / "cut")
    # 1: after the best design's first chunk
    first = Spy(cut, cut_train=1)
    with pytest.raises(KeyboardInterrupt):
        verify(cut, factory=first.factory, eval_factory=first.evaluator)
    state = json.loads((cut.folder / "state.json").read_text())
    assert (
        state["specialists"]["best"]["done"] >= 100 and not state["specialists"]["best"]["finished"]
    )
    # 2: resumed, cut again in the paired check's first block (after the specialists)
    second = Spy(cut, cut_real=1)
    with pytest.raises(KeyboardInterrupt):
        verify(cut, factory=second.factory, eval_factory=second.evaluator)
    # the resumed process trained only what was left: the best's later chunks, the nominal's
    assert second.trains == spy.trains[1:]
    third = Spy(cut)
    resumed = verify(cut, factory=third.factory, eval_factory=third.evaluator)
    assert third.trains == []  # nothing trained again
    for role in ("best", "nominal"):
        a = read_checkpoint(whole.folder / f"checkpoints/specialist-{role}.pt")["ppo"]["actor"]
        b = read_checkpoint(cut.folder / f"checkpoints/specialist-{role}.pt")["ppo"]["actor"]
        assert all(torch.equal(a[k], b[k]) for k in a)
    assert resumed["designs"][0]["specialist"] == uncut["designs"][0]["specialist"]
    assert resumed["designs"][0]["universal"] == uncut["designs"][0]["universal"]
    assert resumed["blocks"] == uncut["blocks"]
    assert not list(cut.folder.glob("checkpoints/*partial*"))


def test_the_command_verifies_a_smoke_run_and_records_its_rows(smoke_run, capsys):
    run = shutil.copytree(smoke_run, smoke_run.parent / "copy-cli")
    store = run.parent.parent / "coadapt.db"
    assert main(["verify", str(run), "--budget", "200", "--threads", "1", "--json"]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    result = json.loads(out[-1])
    assert "best (" in out[1] and "with specialists" in out[2] and "universal" in out[3]
    assert out[4].startswith("  verdict: best: ")
    assert (run / "verify" / "b200-s0" / "verification.json").is_file()
    assert (run / "verify" / "b200-s0" / "checkpoints" / "specialist-best.pt").is_file()
    with ResultsStore(store) as st:
        rows = st.verifications()
    # the copy is not in the store (another run folder, the same run id): its rows go to the
    # run's id all the same
    assert [(r["role"], r["budget"], r["verdict"]) for r in rows] == [
        ("best", 200, result["designs"][0]["verdict"])
    ]
    assert rows[0]["specialist_improvement"] == pytest.approx(
        result["designs"][0]["specialist"]["improvement"]
    )
    # the rows travel with `coadapt export` / `coadapt import` (how a grid's Ray cell returns them)
    exported, merged = run.parent / "export", run.parent / "merged.db"
    assert main(["export", "--store", str(store), "-o", str(exported)]) == 0
    assert main(["import", str(exported), "--store", str(merged)]) == 0
    with ResultsStore(merged) as st:
        again = st.verifications()
    assert [(r["role"], r["verdict"], r["specialist_improvement"]) for r in again] == [
        (r["role"], r["verdict"], r["specialist_improvement"]) for r in rows
    ]
    # the report's column "with specialists"
    report = run.parent / "report"
    assert main(["report", "--store", str(store), "--no-evaluate", "-o", str(report)]) == 0
    table = (report / "table6.md").read_text()
    assert "With specialists (universal): verdict" in table
    verdict_text = result["designs"][0]["verdict"]
    assert f"): {verdict_text} |" in table
    with open(report / "table6.csv", newline="") as fh:
        (row,) = list(csv.DictReader(fh))
    assert float(row["specialist_improvement"]) == pytest.approx(
        result["designs"][0]["specialist"]["improvement"]
    )
    assert row["verdicts"] == verdict_text and row["specialist_budget"] == "200"
    # the paper's Tables 4-5 layout: universal beside the specialist, at the design and nominal
    entry = result["designs"][0]
    with open(report / "specialists.csv", newline="") as fh:
        (spec_row,) = list(csv.DictReader(fh))
    assert float(spec_row["universal_cost"]) == pytest.approx(entry["universal"]["cost"])
    assert float(spec_row["specialist_cost"]) == pytest.approx(entry["specialist"]["cost"])
    assert float(spec_row["specialist_nominal_cost"]) == pytest.approx(
        entry["specialist"]["nominal_cost"]
    )
    assert spec_row["verdict"] == verdict_text
    layout = (report / "specialists.md").read_text()
    assert "| Cost at the design: universal / specialist |" in layout
    capsys.readouterr()
    # a finished verification asked again is read back, not redone
    assert main(["verify", str(run), "--budget", "200", "--json"]) == 0
    assert (
        json.loads(capsys.readouterr().out.strip().splitlines()[-1])["designs"] == result["designs"]
    )


def _refused(capsys, argv, folder) -> str:
    before = sorted(p.name for p in folder.iterdir())
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    assert sorted(p.name for p in folder.iterdir()) == before and not (folder / "verify").exists()
    return err[0]


def test_bad_input_is_one_line_exit_2_and_nothing_created(smoke_run, capsys, tmp_path):
    from coadapt_core.plugins import get_registry

    run = shutil.copytree(smoke_run, tmp_path / "run")
    assert "--budget" in _refused(capsys, ["verify", str(run), "--budget", "0"], run)
    assert "outside the policy's range" in _refused(
        capsys, ["verify", str(run), "--design", "1.9,1.0"], run
    )
    other = get_registry().create("robot", "nezha").shipped_policy("flat")
    assert "robot 'nezha'" in _refused(
        capsys, ["verify", str(run), "--checkpoint", str(other)], run
    )
    assert "one objective" in _refused(capsys, ["verify", str(run), "--pick", "extremes"], run)

    running = shutil.copytree(smoke_run, tmp_path / "running")
    state = load_state(running)
    state.phase = "optimize"
    save_state(running, state)
    assert "has not finished" in _refused(capsys, ["verify", str(running)], running)

    unchecked = shutil.copytree(smoke_run, tmp_path / "unchecked")
    state = load_state(unchecked)
    state.summary = {**state.summary, "final_blocks": 0, "final_scenarios": 0}
    save_state(unchecked, state)
    assert "no final check" in _refused(capsys, ["verify", str(unchecked)], unchecked)


def test_a_run_that_kept_its_nominal_design_has_nothing_to_verify(smoke_run, capsys, tmp_path):
    """A quick tracking run whose candidates all lost to the nominal design fine-tuned two
    specialists at the same design and reported 0.0 +- 0.0 % as "the specialists reverse its
    sign". Now `coadapt verify` refuses it (one line, exit 2, nothing created), `--design` at
    the nominal design likewise, and `coadapt run --verify` says so and goes on."""
    from types import SimpleNamespace

    from coadapt_core.cli.verify import run_stage

    kept = shutil.copytree(smoke_run, tmp_path / "kept")
    state = load_state(kept)
    nominal = list(state.summary["nominal_design"])
    state.summary = {**state.summary, "best_design": nominal}
    save_state(kept, state)
    assert "no improvement to verify" in _refused(capsys, ["verify", str(kept)], kept)
    given = ",".join(f"{x:g}" for x in nominal)
    run = shutil.copytree(smoke_run, tmp_path / "run")
    line = _refused(capsys, ["verify", str(run), "--design", given], run)
    assert "the design given is the nominal design" in line

    before = sorted(p.name for p in kept.iterdir())
    result = SimpleNamespace(run_dir=kept, summary={})
    run_stage(result, {"verify_budget": None, "quiet": False, "as_json": False, "store": None})
    assert "no improvement to verify" in result.summary["verification"]["skipped"]
    assert capsys.readouterr().err.startswith("verify: skipped: ")
    assert sorted(p.name for p in kept.iterdir()) == before


def test_a_verdict_of_two_zero_improvements_says_neither_is_significant():
    from coadapt_core.coadapt.verify_result import verdict_line

    side = {"improvement": 0.0, "improvement_se": 0.0}
    entry = {"role": "best", "universal": side, "specialist": side, "difference": 0.0}
    entry |= {"difference_se": 0.0, "verdict": verdict(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)}
    line = verdict_line(entry)
    assert entry["verdict"] == "does not hold" and "neither improvement" in line, line
    assert "reverse" not in line


def test_run_verify_and_a_two_objective_run_with_the_chosen_design_and_the_fronts_extremes(
    tmp_path, capsys
):
    """`coadapt run --verify` on a two-objective run stores the chosen design's rows; `coadapt
    verify --pick all` then verifies the chosen design and the front's extremes."""
    argv = ["run", "--preset", "smoke", "--objective", "torque,power", "--optimizer", "nsga2"]
    argv += ["--sim", "mujoco", "--seed", "0", "--no-video", "--threads", "1", "--quiet"]
    for key in ("eval_steps", "train_steps", "retrain_steps", "final_max_blocks"):
        argv += ["--" + key.replace("_", "-"), str(SMOKE[key])]
    argv += ["--final-min-blocks", "1", "--out", str(tmp_path / "runs")]
    assert main([*argv, "--verify", "--verify-budget", "150", "--json"]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out.strip().splitlines()[-1])
    assert [d["role"] for d in summary["verification"]["designs"]] == ["chosen"]
    assert "verdict: chosen: " in captured.err  # printed, on stderr with --json
    (run,) = (tmp_path / "runs").glob("2026*")
    with ResultsStore(tmp_path / "coadapt.db") as st:
        rows = st.verifications()
    assert [(r["role"], r["budget"]) for r in rows] == [("chosen", 150)]
    assert rows[0]["verdict"] == summary["verification"]["designs"][0]["verdict"]

    first = json.loads((run / "verify" / "b150-s0" / "verification.json").read_text())
    assert main(["verify", str(run), "--budget", "150", "--pick", "all", "--json"]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    # the chosen design's and the nominal's specialists were kept, the extremes' trained now
    for role in ("chosen", "nominal"):
        assert result["specialists"][role] == first["specialists"][role]
    summary = load_state(run).summary
    roles = [e["role"] for e in result["designs"]]
    assert roles == ["chosen", "lowest-torque", "lowest-power"]
    assert result["designs"][0]["design"] == pytest.approx(summary["best_design"])
    front = summary["pareto_front"]
    for name in ("torque", "power"):
        i = int(np.argmin([c[name] for c in front["costs"]]))
        entry = result["designs"][roles.index(f"lowest-{name}")]
        assert entry["design"] == pytest.approx(front["designs"][i])
    # every verified design and the nominal one had a specialist of the same budget
    specs = result["specialists"]
    assert set(specs) == {*roles, "nominal"}
    assert len({s["interactions"] for s in specs.values()}) == 1
    with ResultsStore(tmp_path / "coadapt.db") as st:
        assert sorted(r["role"] for r in st.verifications()) == [
            "chosen",
            "lowest-power",
            "lowest-torque",
        ]


def test_handoff_hands_off_the_best_designs_specialist_and_says_so(smoke_run, capsys, tmp_path):
    run = shutil.copytree(smoke_run, tmp_path / "run")
    argv = ["handoff", str(run), "--policy", "specialist", "--no-check", "--no-video"]
    argv += ["--sim", "mujoco", "--agents", "2", "--seconds", "0.2", "--threads", "1"]
    argv += ["-o", str(tmp_path / "h1"), "--json"]
    assert main(argv) == 2  # no verification yet: one line
    assert "has no verification" in capsys.readouterr().err
    assert main(["verify", str(run), "--budget", "150", "--store", "none", "--quiet"]) == 0
    capsys.readouterr()
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert "policy: specialist (verify/b150-s0/checkpoints/specialist-best.pt;" in captured.err
    sheet = json.loads((tmp_path / "h1" / "design.json").read_text())
    assert sheet["policies"]["policy"] == "specialist"
    assert sheet["policies"]["design"] == "verify/b150-s0/checkpoints/specialist-best.pt"
    assert sheet["policies"]["nominal"] == "verify/b150-s0/checkpoints/specialist-nominal.pt"
    universal = ["handoff", str(run), "--no-check", "--no-video", "--sim", "mujoco"]
    universal += ["--agents", "2", "--seconds", "0.2", "-o", str(tmp_path / "h2")]
    assert main(universal) == 0
    assert "policy: universal (checkpoints/" in capsys.readouterr().err


def test_grid_verify_is_a_stage_of_every_cell_not_part_of_its_config():
    """`coadapt grid --verify`: every cell's `coadapt run` gets --verify (its rows come back
    with the cell's through export/import), but the grid of the same cells without it keeps
    its id, and a cell's config hash (what finished runs are reused by) does not change."""
    from coadapt_core.experiments.cell_hash import cell_config_hash
    from coadapt_core.experiments.grid_plan import GridSpec

    plain = GridSpec(methods=["ours"], objectives=["torque"], terrains=["flat"], seeds=[0])
    staged = dataclasses.replace(plain, stage_args=["--verify", "--verify-budget", "5000"])
    assert "stage_args" not in plain.to_dict() and plain.grid_id != staged.grid_id
    (cell,) = staged.cells()
    argv = cell.run_args(extra=staged.cell_args)
    assert argv[-4:] == ["--verify", "--verify-budget", "5000", "--json"]
    assert cell_config_hash(cell, staged.extra_args) == cell_config_hash(cell, plain.extra_args)
    assert GridSpec.from_dict(staged.to_dict()) == staged


def test_the_verdict_needs_the_same_sign_and_both_significant():
    assert verdict(0.30, 0.02, 0.29, 0.02, -0.01, 0.01) == "holds"
    assert verdict(0.30, 0.02, 0.20, 0.02, -0.10, 0.02) == "shrinks"
    assert verdict(0.30, 0.02, 0.40, 0.02, 0.10, 0.02) == "grows"
    assert verdict(0.30, 0.02, 0.02, 0.02, -0.28, 0.03) == "does not hold"
    assert verdict(0.30, 0.02, -0.30, 0.02, -0.60, 0.03) == "does not hold"
    assert verdict(0.05, 0.02, 0.30, 0.02, 0.25, 0.03) == "does not hold"


def test_a_specialist_that_falls_more_than_the_universal_policy_says_so_in_the_verdict(tmp_path):
    """Rows: specialist at the best design, at the nominal, universal at the best, at the
    nominal (a [4, A, 1] block): the best design's specialist falls in 20 of 64 scenarios
    where the universal policy fell in none; its verdict line says so."""
    from types import SimpleNamespace

    from coadapt_plugins.objectives.locomotion import TorqueObjective

    from coadapt_core.coadapt.verify import Plan, result_of
    from coadapt_core.costs import CostRule

    rng = np.random.default_rng(0)
    a = 64
    base = rng.uniform(9.0, 11.0, size=a)
    per = np.stack([base * 0.7, base, base * 0.8, base])[:, :, None]
    falls = np.zeros((4, a), dtype=bool)
    falls[0, :20] = True
    plan = Plan(
        run_dir=tmp_path,
        run_id="r",
        config=SimpleNamespace(fall_tolerance=0.01),
        summary={},
        objectives=[TorqueObjective()],
        designs={"best": np.array([0.6, 0.7]), "nominal": np.array([1.0, 1.0])},
        universal=tmp_path / "u.pt",
        budget=100,
        seed=0,
        chunk=100,
        folder=tmp_path / "v",
        min_blocks=1,
        max_blocks=1,
        rule=CostRule("capped"),
    )
    state = {
        "blocks": [{"per_scenario": per, "falls": falls, "interactions": 1, "seconds": 0.0}],
        "specialists": {},
    }
    (entry,) = result_of(plan, state)["designs"]
    assert entry["specialist"]["fall_rate"] == pytest.approx(20 / 64)
    assert entry["universal"]["fall_rate"] == 0.0
    assert len(entry["falls_more"]) == 1
    assert "the best design's specialist falls more than the universal policy" in entry["line"]
    assert "31.2 % of scenarios against 0.0 %" in entry["line"]


def test_ctrl_c_says_the_command_that_continues_and_it_does(
    smoke_run, capsys, tmp_path, monkeypatch
):
    import coadapt_core.coadapt.verify as verify_module

    run = shutil.copytree(smoke_run, tmp_path / "run")
    real = verify_module._evaluate

    def cut(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(verify_module, "_evaluate", cut)  # after both specialists are trained
    argv = ["verify", str(run), "--budget", "100", "--store", "none", "--quiet"]
    assert main(argv) == 130
    err = capsys.readouterr().err
    assert f"continue it with: coadapt verify {run} --budget 100 --store none --quiet" in err
    state = json.loads((run / "verify" / "b100-s0" / "state.json").read_text())
    assert all(s["finished"] for s in state["specialists"].values()) and state["blocks"] == []
    monkeypatch.setattr(verify_module, "_evaluate", real)
    trains = []
    original = verify_module._train_specialist

    def counted(plan, state, role, *args):
        if not state["specialists"].get(role, {}).get("finished"):
            trains.append(role)
        return original(plan, state, role, *args)

    monkeypatch.setattr(verify_module, "_train_specialist", counted)
    assert main([*argv[:-1], "--json"]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert trains == [] and result["blocks"] >= 1  # nothing trained again; the check ran
