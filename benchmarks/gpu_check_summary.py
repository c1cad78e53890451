"""The JSON that benchmarks/gpu_check.sh prints: the throughput steps' results, `coadapt
train`'s iterations and the paper preset's projected wall clock at the measured rates.
Exits 1 (naming what is missing) when a step that ran left no result, so the check never
ends 0 with a JSON of errors.

    python benchmarks/gpu_check_summary.py OUT_FOLDER TRAIN_SECONDS SECONDS
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

#: the paper preset's interactions, as the loop counts them (docs/reproduction.md): training
#: (N = 3 phases of 24 M) and evaluation (real rounds and the final check, about 30 M)
PAPER_TRAINING, PAPER_EVALUATION = 72_000_000, 30_000_000
EPOCHS = 5  # TrainConfig's default, which `coadapt train` in gpu_check.sh keeps


def load(out: Path, name: str) -> dict:
    try:
        return json.loads((out / name).read_text())
    except (OSError, ValueError):
        err = out / name.replace(".json", ".err")
        tail = err.read_text().strip().splitlines()[-3:] if err.exists() else []
        return {"error": "no result", "stderr_tail": tail}


def train_summary(out: Path, train_seconds: float) -> dict | None:
    """`coadapt train`'s iterations (train.jsonl), None when the step did not run."""
    path = out / "train.jsonl"
    if not path.exists():
        return None
    rows = []
    for line in path.read_text().splitlines():
        try:
            row = json.loads(line)
        except ValueError:
            continue
        if "iteration" in row:
            rows.append(row)
    if not rows:
        err = out / "train.err"
        return {
            "error": "no iteration finished",
            "stderr_tail": err.read_text().strip().splitlines()[-3:] if err.exists() else [],
        }

    def rate(
        r: dict,
    ) -> float:  # env steps/s of one iteration: its samples over collection + update time
        samples = r["total_steps"] / r["iteration"]
        return samples / (
            samples / r["collect_steps_per_s"] + samples * EPOCHS / r["update_samples_per_s"]
        )

    later = rows[1:] or rows

    def mean(xs):
        return sum(xs) / len(xs)

    return {
        "wall_seconds": train_seconds,
        "iterations": rows[-1]["iteration"],
        "env_steps": rows[-1]["total_steps"],
        "env_steps_per_s_including_startup": round(rows[-1]["total_steps"] / train_seconds),
        "end_to_end_env_steps_per_s_after_first": round(mean([rate(r) for r in later])),
        "collect_env_steps_per_s": round(mean([r["collect_steps_per_s"] for r in later])),
        "mean_reward_first_last": [
            round(rows[0]["mean_reward"], 4),
            round(rows[-1]["mean_reward"], 4),
        ],
        "learner_share": round(mean([r["learner_share"] for r in later]), 3),
    }


def paper_projection(train: dict | None, throughput: dict) -> dict | None:
    """Hours of the paper preset's 72 M training interactions at the end-to-end rate (coadapt
    train's, else the throughput step's) and 30 M evaluation interactions at the collection
    rate (evaluation is rollouts only), from this machine's measured rates."""
    source = train if train and "error" not in train else None
    end_to_end = (source or {}).get("end_to_end_env_steps_per_s_after_first") or throughput.get(
        "end_to_end_env_steps_per_s"
    )
    collect = (source or {}).get("collect_env_steps_per_s") or throughput.get(
        "collection_env_steps_per_s"
    )
    if not end_to_end or not collect:
        return None
    training_h, evaluation_h = PAPER_TRAINING / end_to_end / 3600, PAPER_EVALUATION / collect / 3600
    return {
        "training_hours": round(training_h, 2),
        "evaluation_hours": round(evaluation_h, 2),
        "total_hours": round(training_h + evaluation_h, 2),
        "rates_from": "coadapt train" if source else "throughput",
        "note": "interactions only: surrogate fits, optimizer and final-check overheads not "
        "included",
    }


def main(argv: list[str]) -> int:
    out, train_seconds, seconds = Path(argv[0]), float(argv[1]), int(argv[2])
    gpu = out / "gpu.txt"
    steps = out / "steps.log"
    result = {
        "gpu": gpu.read_text().strip() if gpu.exists() else None,
        "seconds": seconds,
        "steps": steps.read_text().splitlines() if steps.exists() else [],
    }
    for label in ("default", "bf16"):
        if (out / f"throughput_{label}.json").exists() or label == "default":
            result[f"throughput_{label}"] = load(out, f"throughput_{label}.json")
    train = train_summary(out, train_seconds)
    if train is not None:
        result["train"] = train
    result["paper_preset_projection"] = paper_projection(train, result["throughput_default"])
    text = json.dumps(result, indent=1)
    (out / "gpu_check.json").write_text(text)
    print(text)
    missing = [k for k, v in result.items() if isinstance(v, dict) and "error" in v]
    if missing:
        print(f"gpu_check: no result from {', '.join(missing)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
