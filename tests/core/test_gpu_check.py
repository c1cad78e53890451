"""benchmarks/gpu_check.sh runs the first time (issue 40): a failing step stops it with its
exit code and names the step (set -euo pipefail), its JSON summary exits 1 when a step left
no result and 0 with the paper preset's projection when all did, and `coadapt train`'s
default TensorBoard logger is no requirement (none where tensorboard is not installed)."""

from __future__ import annotations

import json
import os
import subprocess
import tarfile
from pathlib import Path

import pytest

from coadapt_core import tracking
from tests.benchmarks import load_benchmark

ROOT = Path(__file__).resolve().parents[2]


def test_a_failing_step_stops_the_check_with_its_exit_code_and_brings_the_logs_back(tmp_path):
    """A planted failure: an interpreter that fails (`false`) makes the imports step fail."""
    env = {**os.environ, "SKIP_INSTALL": "1", "PYTHON": "false", "OUT": str(tmp_path / "out")}
    done = subprocess.run(
        ["bash", str(ROOT / "benchmarks" / "gpu_check.sh")],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 1, done.stdout + done.stderr
    assert json.loads(done.stdout.splitlines()[0])["error"].startswith(
        "step 'imports' failed (exit 1)"
    )
    with tarfile.open(tmp_path / "out" / "logs.tar.gz") as logs:
        assert "./imports.log" in logs.getnames()
    assert not (tmp_path / "out" / "gpu_check.json").exists()  # no summary of a check that stopped


def _planted(out: Path, train_rows: list[dict] | None) -> None:
    out.mkdir()
    (out / "throughput_default.json").write_text(
        json.dumps({"end_to_end_env_steps_per_s": 10_000, "collection_env_steps_per_s": 20_000})
    )
    if train_rows is not None:
        (out / "train.jsonl").write_text("".join(json.dumps(r) + "\n" for r in train_rows))


def test_the_summary_projects_the_paper_preset_and_exits_0_with_every_result(tmp_path, capsys):
    summary = load_benchmark("gpu_check_summary")
    rows = [
        {
            "iteration": i,
            "total_steps": 4096 * 24 * i,
            "collect_steps_per_s": 30_000.0,
            "update_samples_per_s": 5 * 60_000.0,
            "learner_share": 0.3,
            "mean_reward": 0.01 * i,
        }
        for i in (1, 2, 3)
    ]
    _planted(tmp_path / "ok", [*rows, {"walking_gate": "not judged"}])
    assert summary.main([str(tmp_path / "ok"), "180", "200"]) == 0
    result = json.loads((tmp_path / "ok" / "gpu_check.json").read_text())
    # an iteration: 98 304 samples in 98 304 / 30 000 s of collection + 98 304 / 60 000 s of update
    assert result["train"]["end_to_end_env_steps_per_s_after_first"] == 20_000
    projection = result["paper_preset_projection"]
    assert projection["rates_from"] == "coadapt train"
    assert projection["training_hours"] == pytest.approx(72e6 / 20_000 / 3600, abs=0.01)  # 1.0 h
    assert projection["evaluation_hours"] == pytest.approx(30e6 / 30_000 / 3600, abs=0.01)
    _planted(tmp_path / "bad", [])  # coadapt train ran, but no iteration finished
    assert summary.main([str(tmp_path / "bad"), "180", "200"]) == 1
    assert "no result from train" in capsys.readouterr().err


def test_the_tensorboard_logger_falls_back_to_none_where_tensorboard_is_missing(
    tmp_path, monkeypatch, capsys
):
    monkeypatch.setattr(tracking, "tensorboard_installed", lambda: False)
    logger = tracking.make_logger("tensorboard", tmp_path / "tb")
    logger.log_scalar("train/x", 1.0, 1)
    logger.close()
    assert logger.kind == "none" and not (tmp_path / "tb").exists()
    assert "tensorboard is not installed" in capsys.readouterr().err
