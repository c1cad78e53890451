"""The BO baseline's own policies on real MuJoCo (`coadapt_core.coadapt.specialized`,
`coadapt_core.experiments.own_policies`): a tiny `bo-specialized` run ends with the paired
final check (standard errors, plain mean, fall rates) and leaves its best and nominal
designs' policies in its folder; the common yardstick evaluates each design with its own
policy; and a run folder without them (as runs made before they were kept) gets the very
same rows by training them again with the run's seeds."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.run import run_coadaptation
from coadapt_core.coadapt.specialized import OWN_POLICY_FILES
from coadapt_core.experiments.own_policies import saved_policies, shares_policy
from coadapt_core.experiments.yardstick import yardstick_rows, yardstick_runs
from coadapt_core.learning.checkpoints import read_checkpoint
from coadapt_core.results import SqliteRecorder
from tests.benchmarks import load_benchmark

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[2]

TINY = {
    "method": "bo-specialized",
    "sim": "mujoco",
    "objective": "torque",
    "seed": 2,
    "outer_iterations": 1,
    "bo_designs": 2,
    "specialized_train_steps": 16,
    "population": 2,
    "agents_per_design": 2,
    "eval_agents": 4,
    "eval_steps": 8,
    "final_max_blocks": 2,
    "final_min_blocks": 2,
    "final_candidates": 1,
    "logger": "none",
    "checkpoint": "none",
    "train": {"steps_per_env": 4, "hidden": [16, 16], "epochs": 1, "minibatches": 1},
}


@pytest.fixture(scope="module")
def bo_run(tmp_path_factory):
    """The tiny BO run (its result and its results store), shared by this module's tests."""
    root = tmp_path_factory.mktemp("bo_own_policies")
    db = root / "bo.db"
    config = make_config("smoke", overrides={**TINY, "out": str(root / "runs"), "store": str(db)})
    return run_coadaptation(config), db


def test_a_bo_run_checks_finally_keeps_its_policies_and_old_runs_get_them_again(
    bo_run, tmp_path, capsys
):
    result, db = bo_run
    s = result.summary
    # the paired final check of the shared methods: 2 blocks x 4 scenarios, candidate and nominal
    assert s["final_blocks"] == 2 and s["final_scenarios"] == 8
    assert s["final_interactions"] == 2 * 2 * 4 * 8
    for key in (
        "best_cost_se",
        "nominal_cost_se",
        "best_plain_mean",
        "nominal_plain_mean",
        "best_fall_rate",
        "nominal_fall_rate",
        "fall_rate_difference",
    ):
        assert s[key] is not None and np.isfinite(s[key]), key
    assert s["nominal_cost_se"] > 0 and 0.0 <= s["best_fall_rate"] <= 1.0
    assert not s["best_is_nominal"]  # seed 2: a design other than the nominal one, so two policies
    assert set(s["final_walking"]) == {"best", "nominal"}
    # the best and nominal designs' policies, readable with weights_only=True
    for role, name in OWN_POLICY_FILES.items():
        state = read_checkpoint(result.run_dir / name)
        assert state["robot"] == "kuafu", role
    store = SqliteRecorder(db).store
    run = store.get_run(result.run_id)
    assert not shares_policy(run) and saved_policies(run) is not None
    assert yardstick_runs(store, [run], blocks=2, agents=4, steps=8) == {}
    saved = [(r.design, r.costs) for r in yardstick_rows(store, run["id"])]
    assert saved[0][0] == s["best_design"] and saved[1][0] == s["nominal_design"]
    assert saved[0][1]["torque/se"] > 0 and "falls/difference" in saved[0][1]
    assert saved[0][1]["torque"] != saved[1][1]["torque"]

    # the same run as an older one left it: no policies in its folder, a store of its own
    old = tmp_path / "old" / run["id"]
    shutil.copytree(result.run_dir, old)
    shutil.rmtree(old / "checkpoints")
    other = SqliteRecorder(tmp_path / "old.db").store
    other.create_run(run["config"], run_id=run["id"], run_dir=str(old))
    other.finish_run(run["id"], s)
    old_run = other.get_run(run["id"])
    assert saved_policies(old_run) is None
    assert yardstick_runs(other, [old_run], blocks=2, agents=4, steps=8) == {}
    # trained again with the run's seeds: the same policies, so the same figures to the bit
    assert [(r.design, r.costs) for r in yardstick_rows(other, run["id"])] == saved
    assert not (old / "checkpoints").exists()  # nothing written into the run's folder

    # benchmarks/bo_retrain_check.py on the older folder: the recorded costs, to the bit
    check = load_benchmark("bo_retrain_check")
    assert check.main([str(old), "--json"]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(x["design"], x["equal"]) for x in lines] == [("best", True), ("nominal", True)]
    assert (
        lines[1]["compared"] == "reference level" and lines[1]["recorded"] == s["cost_reference"][0]
    )
    assert (
        check.main([str(tmp_path)]) == 2 and "not a finished run folder" in capsys.readouterr().err
    )


def _older(result, tmp_path):
    """The run's folder as a run made before the policies were kept left it."""
    old = tmp_path / "old" / result.run_dir.name
    shutil.copytree(result.run_dir, old)
    shutil.rmtree(old / "checkpoints")
    return old


def test_the_video_draws_each_design_under_its_own_policy(bo_run, tmp_path, monkeypatch):
    import io

    import yaml

    import coadapt_core.experiments.evaluate as evaluate
    from coadapt_core.viz import video

    result, _ = bo_run
    config = yaml.safe_load((result.run_dir / "config.yaml").read_text())
    real, used = evaluate.evaluate_checkpoint, []

    def spy(checkpoint, robot, sim_cls, design, **kw):
        used.append((Path(checkpoint), list(design)))
        return real(checkpoint, robot, sim_cls, design, **kw)

    monkeypatch.setattr(evaluate, "evaluate_checkpoint", spy)
    drawn = []
    monkeypatch.setattr(
        video,
        "offscreen",
        lambda function, payload, **kw: (drawn.append(payload), (None, ["-"]))[1],
    )
    stream = io.StringIO()
    assert (
        video.render_run_video(result.run_dir, result.summary, config, seconds=0.1, stream=stream)
        == []
    )
    assert used == [
        (result.run_dir / OWN_POLICY_FILES["best"], result.summary["best_design"]),
        (result.run_dir / OWN_POLICY_FILES["nominal"], result.summary["nominal_design"]),
    ]
    assert [p["label"].split()[0] for p in drawn[0]["panels"]] == ["best:", "nominal:"]
    # a run made before the policies were kept: one line, no stand-in policy
    used.clear()
    stream = io.StringIO()
    assert (
        video.render_run_video(_older(result, tmp_path), result.summary, config, stream=stream)
        == []
    )
    assert used == [] and "runs made since keep them" in stream.getvalue()


def test_a_handoff_of_a_bo_run_hands_off_the_best_designs_own_policy(
    bo_run, tmp_path, monkeypatch, capsys
):
    import coadapt_core.learning.factory as factory
    from coadapt_core.cli import main
    from coadapt_core.handoff.policy import missing_deploy_modules
    from coadapt_core.handoff.run_info import sha256

    if missing_deploy_modules():
        pytest.skip("needs the deploy extra (coadapt[deploy])")
    result, _ = bo_run
    run_dir, s = result.run_dir, result.summary
    real, used = factory.make_backend, []

    def spy(*args, checkpoint=None, **kw):
        used.append(Path(checkpoint))
        return real(*args, checkpoint=checkpoint, **kw)

    monkeypatch.setattr(factory, "make_backend", spy)
    out = tmp_path / "handoff"
    args = [
        "handoff",
        str(run_dir),
        "-o",
        str(out),
        "--sim",
        "mujoco",
        "--agents",
        "2",
        "--seconds",
        "0.1",
        "--no-check",
        "--no-video",
        "--json",
    ]
    assert main(args) == 0
    done = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert done["design"] == s["best_design"] and done["is_run_best"]
    # the paired evaluation on MuJoCo: the best design under its policy, the nominal under its own
    assert used == [run_dir / OWN_POLICY_FILES["best"], run_dir / OWN_POLICY_FILES["nominal"]]
    fresh = done["evaluations"][-1]
    assert fresh["simulator"] == "mujoco" and fresh["error"] is None
    assert fresh["objectives"]["torque"]["design"] != fresh["objectives"]["torque"]["nominal"]
    assert fresh["objectives"]["torque"]["improvement_se"] > 0
    assert done["max_abs_action_difference"] <= done["tolerance"]
    sheet = json.loads((out / "design.json").read_text())
    judges = {
        "shared": False,
        "design": OWN_POLICY_FILES["best"],
        "nominal": OWN_POLICY_FILES["nominal"],
    }
    assert {k: sheet["policies"][k] for k in judges} == judges
    assert {
        k: json.loads((out / "policy.json").read_text())["policies"][k] for k in judges
    } == judges
    assert sheet["provenance"]["final_policy_sha256"] == sha256(run_dir / OWN_POLICY_FILES["best"])
    assert sheet["provenance"]["nominal_policy_sha256"] == sha256(
        run_dir / OWN_POLICY_FILES["nominal"]
    )
    assert "nominal design's own" in (out / "design.md").read_text()

    # another design: no policy of its own was kept for it; an older run: none at all
    elsewhere = ",".join(str(x) for x in s["nominal_design"])
    assert main(["handoff", str(run_dir), "-o", str(tmp_path / "x"), "--design", elsewhere]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--design" in err[0] and "none for another design" in err[0]
    assert main(["handoff", str(_older(result, tmp_path)), "-o", str(tmp_path / "y")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert (
        len(err) == 1 and "runs made since keep them" in err[0] and "the handoff does not" in err[0]
    )
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()
