#!/usr/bin/env bash
# One prepared check of the training throughput on the offline GPU machine (one H200 or H100,
# 16 CPU cores, Python 3.12 with torch but without MuJoCo, TorchRL, pymoo or optuna).
#
# Prepare here, once (fills the git-ignored .whl/ with the Python 3.12 wheels it lacks,
# cloudpickle and setuptools >= 77 included):
#     ../shared/tools/device-wheels.sh
# Run through the device tool, from the repository root, carrying the wheels:
#     command: bash benchmarks/gpu_check.sh     carry: [".whl"]     timeout_s: 540
# It installs the wheels and this checkout into a temporary folder (setuptools from the
# wheels builds it: pyproject.toml's `license = "MIT"` needs >= 77), checks every import the
# steps need, then
#   1. benchmarks/train_throughput.py at 4096 environments (128 designs x 32 agents), the
#      learner on the GPU, MuJoCo on every CPU core (TrainConfig's default precisions);
#   2. `coadapt train --logger none` for TRAIN_SECONDS (default 180) of wall time at the same
#      size (no TensorBoard there, none needed);
#   3. the same throughput in bf16, if time is left;
# and prints one JSON object: env steps/s, the learner's share, the paper preset's projected
# wall clock at the measured rates. Any step that fails stops the script with its exit code
# (set -e) and one line naming the step; the logs still come back. Into $OUT (when set; the
# device tool brings back at most 8 files) go only gpu_check.json and logs.tar.gz (every log
# and JSON, no checkpoints).
#
# Knobs (environment): DEVICE (cuda), DESIGNS (128), AGENTS (32), TRAIN_SECONDS (180),
# BUDGET_SECONDS (500: steps that would not finish inside it are skipped), SKIP_INSTALL=1
# (use the Python environment as it is: a rehearsal on a CPU machine with DEVICE=cpu),
# PYTHON (the interpreter with SKIP_INSTALL=1; default .venv/bin/python, else python3).
set -euo pipefail

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
step=setup
elapsed() { echo $(($(date +%s) - begin)); }

finish() {  # on every exit, a failure included: say which step failed, bring the logs back
  local rc=$?
  if [ "$rc" -ne 0 ]; then
    echo "{\"error\": \"step '$step' failed (exit $rc) after $(elapsed) s\"}"
    for log in "$out"/*.err "$out"/*.log; do
      [ -s "$log" ] && { echo "--- $(basename "$log") (last lines)"; tail -5 "$log"; }
    done
  fi
  if [ -n "${OUT:-}" ]; then
    mkdir -p "$OUT"
    cp "$out/gpu_check.json" "$OUT/" 2>/dev/null || true
    tar czf "$OUT/logs.tar.gz" -C "$out" --exclude='*.pt' . 2>/dev/null || true
  fi
  exit "$rc"
}
trap finish EXIT

if [ "${SKIP_INSTALL:-0}" != 1 ]; then
  step=install
  site=$(mktemp -d)
  if ! ls .whl/*.whl >/dev/null 2>&1; then
    echo "no wheels in .whl/: run ../shared/tools/device-wheels.sh here and carry .whl" >"$out/install.log"
    exit 1
  fi
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target "$site" .whl/*.whl \
    >"$out/install.log" 2>&1
  # the checkout itself, with its entry points (built-in plugins), built by the wheels'
  # setuptools (>= 77, what `license = "MIT"` needs), not the machine's older one
  export PYTHONPATH="$site"
  python3 -m pip install -q --no-index --no-deps --no-build-isolation --no-compile --no-cache-dir --target "$site" . \
    >>"$out/install.log" 2>&1
else
  python=${PYTHON:-python3}
  if [ -z "${PYTHON:-}" ] && [ -x .venv/bin/python ]; then
    python=.venv/bin/python
  fi
fi

step=imports  # everything the steps import, so a missing wheel (cloudpickle: tensordict's) fails here, in seconds
$python -c "import cloudpickle, mujoco, tensordict, torch, torchrl; from coadapt_core.plugins import get_registry; \
get_registry().get('simulator', 'mujoco'); print(torch.__version__, mujoco.__version__)" >"$out/imports.log" 2>&1
threads=$($python -c "from coadapt_core.threads import usable_cpus; print(usable_cpus())")
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader >"$out/gpu.txt" 2>/dev/null || true

run_throughput() {  # $1 label, then extra options
  local label=$1
  shift
  step="throughput $label"
  timeout 240 $python benchmarks/train_throughput.py --num-designs "$designs" --agents "$agents" \
    --device "$device" --threads "$threads" --iterations 3 "$@" \
    >"$out/throughput_$label.json" 2>"$out/throughput_$label.err"
  echo "throughput $label: exit 0 after $(elapsed) s" >>"$out/steps.log"
}

run_throughput default  # TrainConfig's precisions

if [ $(( $(elapsed) + train_seconds + 60 )) -lt "$budget" ]; then
  step=train
  # far more steps than fit: the time limit ends the run (timeout's exit 124, expected);
  # progress.jsonl holds every iteration
  rc=0
  timeout -k 30 --signal=INT "$train_seconds" $python -m coadapt_core train --device "$device" --threads "$threads" \
    --num-designs "$designs" --agents "$agents" --steps 1000000000 --seed 0 --quiet --checkpoint-every 100000 \
    --logger none --out "$out/train" >"$out/train.jsonl" 2>"$out/train.err" || rc=$?
  [ "$rc" -eq 0 ] || [ "$rc" -eq 124 ] || exit "$rc"
  echo "train: stopped by its time limit after $(elapsed) s" >>"$out/steps.log"
else
  echo "train: skipped (budget) after $(elapsed) s" >>"$out/steps.log"
fi

if [ $(( $(elapsed) + 150 )) -lt "$budget" ]; then
  run_throughput bf16 --precision bf16 --pseudo-precision bf16
else
  echo "throughput bf16: skipped (budget) after $(elapsed) s" >>"$out/steps.log"
fi

step=summary
$python benchmarks/gpu_check_summary.py "$out" "$train_seconds" "$(elapsed)"
