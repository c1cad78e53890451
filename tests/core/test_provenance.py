"""Every run says which policy it started from: the shipped policy's name and SHA-256 (or the
--checkpoint path's) in config.yaml, summary.json and the store; a resume refuses a policy
file whose hash changed. The loop runs on the analytic fake backend (its logic is what is
tested); the policy files are Kuafu's real shipped ones."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pytest
import yaml

import coadapt_core.coadapt.setup as loop_setup
from coadapt_core.cli import main
from coadapt_core.plugins import get_registry
from coadapt_core.results.store import ResultsStore
from tests.fakes.analytic import AnalyticBackend


@pytest.fixture
def fake_learner(monkeypatch):
    monkeypatch.setattr(
        loop_setup, "universal_policy_factory", lambda *a, **k: lambda seed: AnalyticBackend(seed)
    )


def sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def shipped(terrain: str = "flat") -> Path:
    robot = get_registry().create("robot", get_registry().default("robot"))
    path = robot.shipped_policy(terrain, False)
    assert path is not None, f"the default robot ships no {terrain} policy"
    return Path(path)


def test_a_default_run_records_the_shipped_policy_and_its_hash(tmp_path, fake_learner, capsys):
    store = tmp_path / "runs.db"
    assert (
        main(
            [
                "run",
                "--preset",
                "smoke",
                "--out",
                str(tmp_path / "runs"),
                "--store",
                str(store),
                "--json",
                "--no-video",
            ]
        )
        == 0
    )
    line = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    run_dir = tmp_path / "runs" / line["run_id"]
    expected = {
        "source": "shipped",
        "file": shipped().name,
        "path": str(shipped().resolve()),
        "sha256": sha256(shipped()),
        "robot": get_registry().default("robot"),
    }
    config = yaml.safe_load((run_dir / "config.yaml").read_text())
    assert config["checkpoint"] == ""  # what the user gave: nothing ...
    assert config["policy"] == expected  # ... and what that meant
    assert json.loads((run_dir / "summary.json").read_text())["policy"] == expected
    with ResultsStore(store) as results:
        run = results.get_run(line["run_id"])
    assert run["config"]["policy"] == expected and run["summary"]["policy"] == expected
    # a run folder's config.yaml given back to --config repeats the run (policy is a record,
    # not a setting)
    assert (
        main(
            [
                "run",
                "--config",
                str(run_dir / "config.yaml"),
                "--out",
                str(tmp_path / "again"),
                "--store",
                "none",
                "--json",
                "--no-video",
            ]
        )
        == 0
    )


def test_from_scratch_records_none(tmp_path, fake_learner, capsys):
    assert (
        main(
            [
                "run",
                "--preset",
                "smoke",
                "--checkpoint",
                "none",
                "--out",
                str(tmp_path),
                "--store",
                "none",
                "--json",
                "--no-video",
            ]
        )
        == 0
    )
    line = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    summary = json.loads((tmp_path / line["run_id"] / "summary.json").read_text())
    assert summary["policy"] == {"source": "none", "file": None, "path": None, "sha256": None}


class Stop(Exception):
    pass


def test_resume_refuses_a_policy_file_that_changed(tmp_path, fake_learner, capsys):
    from coadapt_core.coadapt.config_loading import make_config
    from coadapt_core.coadapt.run import run_coadaptation

    policy = tmp_path / "policy.pt"
    shutil.copy(shipped("flat"), policy)
    config = make_config(
        "smoke",
        overrides={"checkpoint": str(policy), "out": str(tmp_path / "runs"), "store": "none"},
    )

    def stop_after_first_round(event):
        if event["phase"] == "evaluated":
            raise Stop

    with pytest.raises(Stop):
        run_coadaptation(config, progress=stop_after_first_round)
    (run_dir,) = (tmp_path / "runs").iterdir()
    state = json.loads((run_dir / "state.json").read_text())
    assert state["policy"]["source"] == "path" and state["policy"]["sha256"] == sha256(policy)

    shutil.copy(shipped("slope"), policy)  # another policy of the same robot under the same name
    assert sha256(policy) != state["policy"]["sha256"]
    capsys.readouterr()
    assert main(["run", "--resume", str(run_dir), "--json", "--no-video"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert (
        len(err) == 1 and "starting policy" in err[0] and "changed since the run started" in err[0]
    ), err

    shutil.copy(shipped("flat"), policy)  # the file it started from: the resume goes on
    assert main(["run", "--resume", str(run_dir), "--json", "--no-video"]) == 0
    assert json.loads((run_dir / "summary.json").read_text())["status"] == "finished"
