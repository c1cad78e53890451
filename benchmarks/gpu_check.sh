#!/usr/bin/env bash
# One prepared check of the training throughput on the offline GPU machine (one H200 or H100,
# 16 CPU cores, Python 3.12 with torch but without MuJoCo, TorchRL, pymoo or optuna).
#
# Prepare here, once (fills the git-ignored .whl/ with the Python 3.12 wheels it lacks):
#     ../shared/tools/device-wheels.sh
# Run through the device tool, from the repository root, carrying the wheels:
#     command: bash benchmarks/gpu_check.sh     carry: [".whl"]     timeout_s: 540
# It installs the wheels and this checkout into a temporary folder, then
#   1. benchmarks/train_throughput.py at 4096 environments (128 designs x 32 agents), the
#      learner on the GPU, MuJoCo on every CPU core (TrainConfig's default precisions, then
#      everything in bf16 if time is left);
#   2. `coadapt train` for TRAIN_SECONDS (default 180) of wall time at the same size;
# and prints one JSON object. Into $OUT (when set; the device tool brings back at most 8 files)
# go only gpu_check.json and logs.tar.gz (every log and JSON, no checkpoints).
#
# Knobs (environment): DEVICE (cuda), DESIGNS (128), AGENTS (32), TRAIN_SECONDS (180),
# BUDGET_SECONDS (500: steps that would not finish inside it are skipped), SKIP_INSTALL=1
# (use the Python environment as it is: for a dry run on a CPU machine with DEVICE=cpu).
set -uo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
begin=$(date +%s)
device=${DEVICE:-cuda}
designs=${DESIGNS:-128}
agents=${AGENTS:-32}
train_seconds=${TRAIN_SECONDS:-180}
budget=${BUDGET_SECONDS:-500}
out=$(mktemp -d)  # logs and results; $OUT receives a copy at the end
export PYTHONUNBUFFERED=1 MUJOCO_GL=disable
python=python3
elapsed() { echo $(($(date +%s) - begin)); }

if [ "${SKIP_INSTALL:-0}" != 1 ]; then
  site=$(mktemp -d)
  if ! ls .whl/*.whl >/dev/null 2>&1; then
    echo '{"error": "no wheels in .whl/: run ../shared/tools/device-wheels.sh here and carry .whl"}'
    exit 1
  fi
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target "$site" .whl/*.whl \
    >"$out/install.log" 2>&1 || { echo '{"error": "installing the wheels failed"}'; tail -20 "$out/install.log"; exit 1; }
  # the checkout itself, with its entry points (built-in plugins): setuptools is on the machine
  python3 -m pip install -q --no-index --no-deps --no-build-isolation --no-compile --no-cache-dir --target "$site" . \
    >>"$out/install.log" 2>&1 || { echo '{"error": "installing coadapt failed"}'; tail -20 "$out/install.log"; exit 1; }
  export PYTHONPATH="$site"
  python=python3
else
  [ -x .venv/bin/python ] && python=.venv/bin/python
fi
threads=$($python -c "import os; print(len(os.sched_getaffinity(0)))")
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader >"$out/gpu.txt" 2>/dev/null || true

run_throughput() {  # $1 label, then extra options
  local label=$1
  shift
  timeout 240 $python benchmarks/train_throughput.py --num-designs "$designs" --agents "$agents" \
    --device "$device" --threads "$threads" --iterations 3 "$@" \
    >"$out/throughput_$label.json" 2>"$out/throughput_$label.err"
  echo "throughput $label: exit $? after $(elapsed) s" >>"$out/steps.log"
}

run_throughput default  # TrainConfig's precisions

if [ $(( $(elapsed) + train_seconds + 60 )) -lt "$budget" ]; then
  # far more steps than fit: the time limit ends the run; progress.jsonl holds every iteration
  timeout -k 30 --signal=INT "$train_seconds" $python -m coadapt_core train --device "$device" --threads "$threads" \
    --num-designs "$designs" --agents "$agents" --steps 1000000000 --seed 0 --quiet --checkpoint-every 100000 \
    --out "$out/train" >"$out/train.jsonl" 2>"$out/train.err"
  echo "train: exit $? after $(elapsed) s" >>"$out/steps.log"
else
  echo "train: skipped (budget) after $(elapsed) s" >>"$out/steps.log"
fi

if [ $(( $(elapsed) + 150 )) -lt "$budget" ]; then
  run_throughput bf16 --precision bf16 --pseudo-precision bf16
else
  echo "throughput bf16: skipped (budget) after $(elapsed) s" >>"$out/steps.log"
fi

$python - "$out" "$train_seconds" "$(elapsed)" <<'EOF'
import json, sys
from pathlib import Path

out, train_seconds, seconds = Path(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])


def load(name):
    try:
        return json.loads((out / name).read_text())
    except (OSError, ValueError):
        err = out / name.replace(".json", ".err")
        tail = err.read_text().strip().splitlines()[-3:] if err.exists() else []
        return {"error": "no result", "stderr_tail": tail}


result = {"gpu": (out / "gpu.txt").read_text().strip() if (out / "gpu.txt").exists() else None,
          "seconds": seconds, "steps": (out / "steps.log").read_text().splitlines()}
for label in ("default", "bf16"):
    if (out / f"throughput_{label}.json").exists() or label == "default":
        result[f"throughput_{label}"] = load(f"throughput_{label}.json")
rows = []
for line in (out / "train.jsonl").read_text().splitlines() if (out / "train.jsonl").exists() else []:
    try:
        rows.append(json.loads(line))
    except ValueError:
        pass
if rows:
    epochs = 5  # TrainConfig's default, which coadapt train above keeps

    def rate(r):  # env steps/s of one iteration: its samples over collection + update time
        samples = r["total_steps"] / r["iteration"]
        collect = samples / r["collect_steps_per_s"]
        update = samples * epochs / r["update_samples_per_s"]  # that field counts sample-epochs
        return samples / (collect + update)

    later = rows[1:] or rows
    mean = lambda xs: sum(xs) / len(xs)  # noqa: E731
    result["train"] = {
        "wall_seconds": train_seconds, "iterations": rows[-1]["iteration"], "env_steps": rows[-1]["total_steps"],
        "env_steps_per_s_including_startup": round(rows[-1]["total_steps"] / train_seconds),
        "end_to_end_env_steps_per_s_after_first": round(mean([rate(r) for r in later])),
        "collect_env_steps_per_s": round(mean([r["collect_steps_per_s"] for r in later])),
        "mean_reward_first_last": [round(rows[0]["mean_reward"], 4), round(rows[-1]["mean_reward"], 4)],
        "learner_share": round(mean([r["learner_share"] for r in later]), 3),
    }
else:
    err = out / "train.err"
    result["train"] = {"error": "no iteration finished",
                       "stderr_tail": err.read_text().strip().splitlines()[-3:] if err.exists() else []}
text = json.dumps(result, indent=1)
(out / "gpu_check.json").write_text(text)
print(text)
EOF
if [ -n "${OUT:-}" ]; then
  mkdir -p "$OUT"
  cp "$out/gpu_check.json" "$OUT/" 2>/dev/null
  tar czf "$OUT/logs.tar.gz" -C "$out" --exclude='*.pt' . 2>/dev/null
fi
