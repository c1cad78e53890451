"""How fast the `coadapt` command answers: wall-clock seconds of `coadapt --help`, `coadapt
plugins`, a `--help` page and three refusals of bad input, each the median of `--repeat` fresh
processes, beside two ceilings measured in the same run on the same machine: `python -c pass`
(the interpreter alone) and `python -c "import typer"` (the command-line library alone). The
goal (issue 50) is about a second on a 2-core machine; a command that answers without torch
costs the interpreter, typer, numpy and coadapt's settings. Each line also says whether the
command loaded torch (`-X importtime`), which is what makes a command slow.

    python benchmarks/cli_startup.py [--repeat 5] [--json]

Prints one JSON object with --json, else a table. Not a test: timings depend on the
machine and its load (docs/status.md quotes the figures).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

#: (label, arguments after `python -m coadapt_core`, exit status expected)
COMMANDS = (
    ("coadapt --help", ["--help"], 0),
    ("coadapt plugins", ["plugins"], 0),
    ("coadapt report --help", ["report", "--help"], 0),
    ("coadapt run --preset smok (refused)", ["run", "--preset", "smok"], 2),
    ("coadapt report --transfer-agents 0 (refused)", ["report", "--transfer-agents", "0"], 2),
    ("coadapt export --format parket (refused)", ["export", "-o", "x", "--format", "parket"], 2),
)
CEILINGS = (
    ("python -c pass", ["-c", "pass"]),
    ("python -c 'import typer'", ["-c", "import typer"]),
)


def _time(args: list[str], expected: int | None, repeat: int) -> dict:
    """Median wall-clock seconds of `python args` over `repeat` fresh processes, and whether
    torch was imported (one extra run with -X importtime)."""
    env = {**os.environ, "COLUMNS": "80"}
    seconds = []
    for _ in range(repeat):
        start = time.perf_counter()
        done = subprocess.run([sys.executable, *args], capture_output=True, env=env, check=False)
        seconds.append(time.perf_counter() - start)
        if expected is not None and done.returncode != expected:
            raise SystemExit(
                f"{' '.join(args)} exited {done.returncode}, not {expected}: "
                + done.stderr.decode()[-500:]
            )
    traced = subprocess.run(
        [sys.executable, "-X", "importtime", *args], capture_output=True, env=env, check=False
    )
    loaded = {line.split("|")[-1].strip() for line in traced.stderr.decode().splitlines()}
    return {
        "seconds": round(statistics.median(seconds), 3),
        "min_seconds": round(min(seconds), 3),
        "imports_torch": "torch" in loaded,
        "first_line": next(iter((done.stdout or done.stderr).decode().splitlines()), "")[:100],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5, help="fresh processes per command")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)
    out = {
        "repeat": args.repeat,
        "cpus": os.cpu_count(),
        "load_average": [round(x, 2) for x in os.getloadavg()],
        "ceilings": {label: _time(a, 0, args.repeat) for label, a in CEILINGS},
        "commands": {
            label: _time(["-m", "coadapt_core", *a], code, args.repeat)
            for label, a, code in COMMANDS
        },
    }
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(f"{'command':48} {'median s':>9} {'min s':>7}  torch")
    for group in ("ceilings", "commands"):
        for label, r in out[group].items():
            torch = "yes" if r["imports_torch"] else "no"
            print(f"{label:48} {r['seconds']:9.3f} {r['min_seconds']:7.3f}  {torch}")
    print(f"load average {out['load_average']} on {out['cpus']} CPUs, {args.repeat} runs each")
    return 0


if __name__ == "__main__":
    sys.exit(main())
