"""benchmarks/coadapt_cost.py on the analytic backend: a Table 7 layout with the paper's
interaction accounting reproduced at the paper preset."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.benchmarks import load_benchmark

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_paper_preset_on_fake_reproduces_table7_interaction_counts(tmp_path, capsys):
    bench = load_benchmark("coadapt_cost")
    assert (
        bench.main(
            [
                "--fake",
                "--preset",
                "paper",
                "--out",
                str(tmp_path),
                "--methods",
                "ours,no-surrogate,no-real",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "| ours |" in out and "ours / no-surrogate" in out
    payload = json.loads(out.strip().splitlines()[-1])
    rows = {r["method"]: r for r in payload["rows"]}
    # K = 100 designs x 50 agents x T_eval = 800 steps = 4 M interactions per real round
    assert rows["no-surrogate"]["eval_interactions"] == 15 * 4_000_000  # 60 M, as in Table 7
    assert rows["no-real"]["eval_interactions"] == 0
    assert rows["ours"]["train_interactions"] == 72_000_000
    assert rows["ours"]["designs_evaluated"] == 1500  # "evaluates 1500 designs"
    assert 0.6 < payload["ratios_ours_over_no_surrogate"]["interactions"] < 0.95


def test_unknown_method_is_exit_2(capsys):
    assert load_benchmark("coadapt_cost").main(["--fake", "--methods", "ours,magic"]) == 2
    assert "magic" in capsys.readouterr().err


@pytest.mark.parametrize("method", ["no-retrain", "bo-specialized"])
def test_smoke_preset_each_method_runs(tmp_path, capsys, method):
    assert (
        load_benchmark("coadapt_cost").main(["--fake", "--out", str(tmp_path), "--methods", method])
        == 0
    )
    payload = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert payload["rows"][0]["method"] == method and payload["rows"][0]["best_cost"] > 0
