"""How well does the surrogate's gradient in the design point where the real cost falls?
(issue 52). With the shipped Kuafu flat policy: over a grid of designs, at two scenario
seeds, the cosine between the surrogate's gradient (`surrogate_slope`, the paper's estimator
on the states of the rollouts just made) and the real cost's central finite-difference
gradient (each design +- `h` along each variable, every design of a seed on the same paired
scenarios), in the full range and inside a narrowed one.

Beside it, the real gradient's own reproducibility: the cosine between the finite
differences of two halves of the scenarios (a ceiling any estimator's agreement with a
noisy real gradient is held under), and its signal to noise (|gradient| over its standard
error over scenarios). Costs are the plain mean over scenarios (eq. 4), what the
pseudo-critics estimate. The narrowed range is read with the same full-range policy (a run
retrains on it; this benchmark does not).

    python benchmarks/surrogate_slope.py                       # 2 x 2 grid per range, torque
    python benchmarks/surrogate_slope.py --grid 3 --agents 32 --steps 250 --json
    python benchmarks/surrogate_slope.py --objective power --seeds 0,1

Mean +- standard error over the designs of both seeds (and per seed).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
NOMINAL = np.array([1.0, 1.0])  # Kuafu's nominal scales: the cost rule's reference design


def cosine(a: np.ndarray, b: np.ndarray) -> float:
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    return float(a @ b / (na * nb)) if na > 0 and nb > 0 else float("nan")


def mean_se(values: list[float]) -> dict:
    v = np.asarray([x for x in values if np.isfinite(x)], dtype=float)
    if v.size == 0:
        return {"mean": None, "se": None, "n": 0}
    se = float(v.std(ddof=1) / np.sqrt(v.size)) if v.size > 1 else None
    return {
        "mean": round(float(v.mean()), 3),
        "se": None if se is None else round(se, 3),
        "n": int(v.size),
    }


def probe_designs(centres: np.ndarray, h: float) -> np.ndarray:
    """[n (1 + 2 D), D]: each centre, then +h and -h along each variable."""
    d = centres.shape[1]
    steps = h * np.eye(d)
    plus = (centres[:, None] + steps).reshape(-1, d)
    minus = (centres[:, None] - steps).reshape(-1, d)
    return np.concatenate([centres, plus, minus])


def real_gradients(per: np.ndarray, n: int, d: int, h: float) -> np.ndarray:
    """[n, A, D] each scenario's central difference, from per-scenario costs [K, A]."""
    plus = per[n : n + n * d].reshape(n, d, -1)
    minus = per[n + n * d :].reshape(n, d, -1)
    return ((plus - minus) / (2 * h)).transpose(0, 2, 1)


def one_range(backend, objective, centres, h, *, agents, steps, seed, samples, rule) -> dict:
    """Real and surrogate gradients at `centres`; the real one from the plain mean and from
    the run's cost rule (`rule`, its reference the nominal design's, evaluated alongside)."""
    from coadapt_core.scenarios.seeds import scenario_seed

    n, d = centres.shape
    t0 = time.perf_counter()
    designs = np.concatenate([probe_designs(centres, h), NOMINAL[None]])
    fit = backend.real_fitness(
        designs, [objective], agents=agents, steps=steps, seed=scenario_seed(seed)
    )
    per = np.asarray(fit.per_scenario, dtype=float)  # [K, A, 1]
    falls = np.asarray(fit.scenario_falls)
    ref = rule.reference(per[-1], falls[-1]) if rule.needs_reference else None
    ruled = rule.scenario_values(per[:-1], falls[:-1], ref)[:, :, 0]
    _, slope = backend.surrogate_slope(centres, [objective], fit.buffer, samples=samples, seed=seed)
    slope = slope[:, 0]  # [n, D]
    out = {"surrogate_gradient": np.round(slope, 4).tolist()}
    for label, values in (("", per[:-1, :, 0]), ("_" + rule.rule, ruled)):
        fd = real_gradients(values, n, d, h)  # [n, A, D]
        real = fd.mean(axis=1)
        se = fd.std(axis=1, ddof=1) / np.sqrt(fd.shape[1])
        half = fd.shape[1] // 2
        out |= {
            f"cosine{label}": [cosine(slope[i], real[i]) for i in range(n)],
            f"split_half{label}": [
                cosine(fd[i, :half].mean(0), fd[i, half:].mean(0)) for i in range(n)
            ],
            f"snr{label}": [
                float(np.linalg.norm(real[i]) / np.linalg.norm(se[i])) for i in range(n)
            ],
            f"real_gradient{label}": np.round(real, 4).tolist(),
            f"real_gradient_se{label}": np.round(se, 4).tolist(),
        }
    out |= {
        "fall_rate": float(np.mean(fit.fall_rate[:-1])),
        "seconds": round(time.perf_counter() - t0, 1),
        "interactions": int(fit.interactions),
    }
    return out


def summarise(rows: list[dict], rule: str) -> dict:
    keys = [f"{k}{label}" for label in ("", "_" + rule) for k in ("cosine", "split_half", "snr")]
    out = {k: mean_se([x for r in rows for x in r[k]]) for k in keys}
    out["cosine_per_seed"] = [mean_se(r["cosine"]) for r in rows]
    out[f"cosine_{rule}_per_seed"] = [mean_se(r[f"cosine_{rule}"]) for r in rows]
    return out


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--objective", default="torque")
    p.add_argument("--grid", type=int, default=2, help="points per axis in each range")
    p.add_argument("--agents", type=int, default=32, help="paired scenarios per design")
    p.add_argument("--steps", type=int, default=250, help="policy steps per scenario")
    p.add_argument("--seeds", default="0,1", help="two scenario seeds")
    p.add_argument("--samples", type=int, default=4096, help="buffer states the surrogate reads")
    p.add_argument("--full", default="0.5:1.5", help="the full range of both scales, LOW:HIGH")
    p.add_argument("--narrow", default="0.5:0.7", help="the narrowed range, LOW:HIGH")
    p.add_argument("--cost-rule", default="capped", help="the run's rule beside the plain mean")
    p.add_argument("--step", type=float, default=0.1, help="h as a fraction of each range")
    p.add_argument("--json", action="store_true", help="print one JSON line last")
    return p


def _args(argv: list[str] | None):
    """The arguments checked; a bad one is one line naming it (None)."""
    args = _parser().parse_args(argv)
    try:
        args.seeds = [int(s) for s in args.seeds.split(",")]
        args.ranges = {
            name: tuple(float(v) for v in text.split(":"))
            for name, text in (("full", args.full), ("narrowed", args.narrow))
        }
    except ValueError:
        print("error: --seeds must be integers a,b and ranges LOW:HIGH", file=sys.stderr)
        return None
    for name, value, ok in (
        ("--grid", args.grid, args.grid >= 1),
        ("--agents", args.agents, args.agents >= 4),
        ("--steps", args.steps, args.steps >= 1),
        ("--samples", args.samples, args.samples >= 1),
        ("--step", args.step, 0 < args.step < 0.5),
        ("--seeds", args.seeds, len(args.seeds) == 2),
        ("--cost-rule", args.cost_rule, args.cost_rule in ("capped", "mean", "trimmed")),
    ):
        if not ok:
            print(f"error: {name} is out of range, got {value}", file=sys.stderr)
            return None
    return args


def main(argv: list[str] | None = None) -> int:
    sys.path.insert(0, str(ROOT))
    args = _args(argv)
    if args is None:
        return 2
    from coadapt_core.costs import CostRule
    from coadapt_core.learning import shipped_checkpoint
    from coadapt_core.learning.factory import make_backend, resolve_plugins

    rule = CostRule(args.cost_rule, 3.0)
    checkpoint = shipped_checkpoint("kuafu", "flat")
    robot, sim_cls, objectives = resolve_plugins("kuafu", "mujoco", [args.objective])
    backend = make_backend(
        robot,
        sim_cls,
        objectives,
        terrain="flat",
        checkpoint=str(checkpoint),
        agents_per_design=args.agents,
    )
    result: dict = {
        "objective": args.objective,
        "policy": Path(checkpoint).name,
        "grid": args.grid,
        "agents": args.agents,
        "steps": args.steps,
        "seeds": args.seeds,
        "samples": args.samples,
        "ranges": {},
    }
    t0 = time.perf_counter()
    for name, (low, high) in args.ranges.items():
        h = args.step * (high - low)
        axis = np.linspace(low + h, high - h, args.grid) if args.grid > 1 else [(low + high) / 2]
        centres = np.array([[a, b] for a in axis for b in axis])
        rows = [
            one_range(
                backend,
                objectives[0],
                centres,
                h,
                agents=args.agents,
                steps=args.steps,
                seed=s,
                samples=args.samples,
                rule=rule,
            )
            for s in args.seeds
        ]
        result["ranges"][name] = {
            "low": low,
            "high": high,
            "h": h,
            "centres": centres.tolist(),
            **summarise(rows, rule.rule),
            "per_seed": rows,
        }
        s = result["ranges"][name]
        for label in ("", "_" + rule.rule):
            print(
                f"{name:9s} [{low}, {high}]^2, h {h:.3f}, {label[1:] or 'plain mean'}: cosine "
                f"{s['cosine' + label]['mean']} +- {s['cosine' + label]['se']} "
                f"(n {s['cosine' + label]['n']}), split-half {s['split_half' + label]['mean']} "
                f"+- {s['split_half' + label]['se']}, SNR {s['snr' + label]['mean']} +- "
                f"{s['snr' + label]['se']}"
            )
    result["seconds"] = round(time.perf_counter() - t0, 1)
    backend.close()
    if args.json:
        print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
