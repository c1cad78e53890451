"""benchmarks/time_to_walk_curves.py: the first check that walks is the run's time to walk,
the worst of the five designs is what the curve shows, a bad name is one line and exit 2."""

from __future__ import annotations

import json

from tests.benchmarks import load_benchmark


def _check(steps, seconds, ratios, survivals, walking):
    names = ("nominal", "lower", "upper", "alternate", "alternate_mirror")
    return json.dumps(
        {
            "iteration": steps // 100,
            "interactions": steps,
            "train_seconds": seconds,
            "mean_reward": 0.01 * seconds,
            "walking": walking,
            "designs": {
                n: {"survival": s, "tracking_ratio": r, "vx_mean": 0.1, "walking": walking}
                for n, r, s in zip(names, ratios, survivals, strict=True)
            },
        }
    )


def test_first_walking_check_and_worst_design(tmp_path, capsys):
    bench = load_benchmark("time_to_walk_curves")
    log = tmp_path / "small-s1.log"
    log.write_text(
        "\n".join(
            [
                _check(100, 10.0, [0.9, 1.0, 0.8, 0.7, 0.95], [1, 1, 0.5, 1, 1], False),
                _check(200, 20.0, [0.3, 0.4, 0.45, 0.2, 0.1], [1, 1, 0.9, 1, 1], True),
                "a line that is not JSON",
                _check(300, 30.0, [0.3, 0.6, 0.45, 0.2, 0.1], [1, 1, 1, 1, 1], False),
            ]
        )
    )
    curve = bench.read_curve(log)
    assert curve["arm"] == "small" and curve["seed"] == 1
    assert [r["worst_tracking"] for r in curve["rows"]] == [1.0, 0.45, 0.6]
    assert [r["worst_survival"] for r in curve["rows"]] == [0.5, 0.9, 1.0]
    assert curve["walked"]["interactions"] == 200 and curve["walked"]["seconds"] == 20.0
    png = tmp_path / "curves.png"
    assert bench.main([str(log), "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "| small | 1 | yes | 200 | 20 | 300, 30, 0.60, 1.00 |" in out
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"


def test_a_log_without_a_seed_in_its_name_is_one_line(tmp_path, capsys):
    bench = load_benchmark("time_to_walk_curves")
    log = tmp_path / "small.log"
    log.write_text("")
    assert bench.main([str(log)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "ARM-sSEED" in err[0]
