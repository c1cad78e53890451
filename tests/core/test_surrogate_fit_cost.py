"""benchmarks/surrogate_fit_cost.py: each fit variant is timed and judged on held-out designs
(real MuJoCo, a tiny round), the variant's settings reach the fit, and bad input is one line
with exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.benchmarks import load_benchmark

ROOT = Path(__file__).resolve().parents[2]


def test_variants_parse_and_bad_ones_name_the_item():
    bench = load_benchmark("surrogate_fit_cost")
    assert bench.parse_variants("5x128x200, 3X64x100") == [(5, 128, 200), (3, 64, 100)]
    for bad in ("5x128", "5x0x3", "ax1x1"):
        with pytest.raises(ValueError, match=bad.split(",")[0]):
            bench.parse_variants(bad)


@pytest.mark.parametrize(
    "args",
    [["--variants", "5x0x3"], ["--held-out", "1"], ["--seeds", "a,b"], ["--check-states", "0"]],
)
def test_bad_input_is_one_line_and_exit_2(args, capsys):
    with pytest.raises(SystemExit) as stop:
        load_benchmark("surrogate_fit_cost").main(args)
    assert stop.value.code == 2
    assert len([line for line in capsys.readouterr().err.splitlines() if "error" in line]) == 1


def test_a_tiny_round_times_and_ranks_each_variant(capsys, monkeypatch):
    from coadapt_core.learning import surrogate

    seen = []
    real_fit = surrogate.fit_ensemble

    def spy(*args, **kwargs):
        seen.append((kwargs["members"], kwargs["batch"], kwargs["steps"], kwargs["check_states"]))
        return real_fit(*args, **kwargs)

    monkeypatch.setattr("coadapt_core.learning.backend.fit_ensemble", spy)
    code = load_benchmark("surrogate_fit_cost").main(
        [
            "--variants",
            "3x16x4,2x8x2",
            "--objectives",
            "torque",
            "--designs",
            "8",
            "--held-out",
            "4",
            "--agents",
            "2",
            "--steps",
            "10",
            "--seeds",
            "0,1",
            "--samples",
            "64",
            "--check-states",
            "32",
            "--json",
        ]
    )
    assert code == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert set(out["variants"]) == {"3x16x4", "2x8x2"}
    for per in out["variants"].values():
        assert len(per["torque"]["spearman"]) == 2
        assert all(-1.0 <= r <= 1.0 for r in per["torque"]["spearman"])
        assert per["torque"]["fit_seconds"] > 0
        assert len(per["torque"]["mean_relative_error"]) == 2
        assert all(e >= 0.0 for e in per["torque"]["mean_relative_error"])
    # each variant's settings, and the level check's states, reached the fit
    assert seen == [(3, 16, 4, 32), (3, 16, 4, 32), (2, 8, 2, 32), (2, 8, 2, 32)]
    assert out["check_states"] == 32 and out["samples"] == 64
