"""How fast the `coadapt` command answers: wall-clock seconds of `coadapt --help`, `coadapt
plugins`, `--help` pages and refusals of bad input, each the median of `--repeat` fresh
processes, beside two ceilings measured in the same run on the same machine: `python -c pass`
(the interpreter alone) and `python -c "import typer"` (the command-line library alone). The
goal (issue 61): every command that runs no physics answers in at most 0.3 s on a quiet
2-core machine, and in at most twice `import typer` under load (`within 2x typer`). Each
line also gives the command's import profile, from one more run under `python -X
importtime`: the 5 modules of largest cumulative import time among those imported at the top
level (a module imported by another is counted in its importer's time, so the five do not
overlap), and whether it loaded torch, numpy or pydantic. `cpu s` is the median CPU time
(user + system) of the command's process: on a loaded machine it stands in for the wall
time of a quiet one (one thread; it still grows somewhat with the load, through the caches
the other processes share).

    python benchmarks/cli_startup.py [--repeat 5] [--json] [--work] [--cold]

The timed processes find their bytecode cached, as an installed copy does (`.pyc` files in a
folder of the temporary directory when the environment sets PYTHONDONTWRITEBYTECODE; one
untimed run writes them); `--cold` compiles every module in every run instead, as a checkout
that cannot write its `.pyc` files (up to 0.13 s more per command on the 2-core machine).
`--work` adds commands that do their work (`coadapt robot show kuafu`: it builds the model,
which takes numpy, and checks it, which takes Pinocchio and MuJoCo), to name what they load.

Prints one JSON object with --json, else a table. Not a test: timings depend on the
machine and its load (docs/status.md quotes the figures).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

#: (label, arguments after `python -m coadapt_core`, exit status expected)
COMMANDS = (
    ("coadapt --help", ["--help"], 0),
    ("coadapt plugins", ["plugins"], 0),
    ("coadapt report --help", ["report", "--help"], 0),
    ("coadapt run --help", ["run", "--help"], 0),
    ("coadapt run --preset smok (refused)", ["run", "--preset", "smok"], 2),
    ("coadapt run --sim mujocoo (refused)", ["run", "--sim", "mujocoo"], 2),
    ("coadapt run --optimizer nope (refused)", ["run", "--optimizer", "nope"], 2),
    ("coadapt report --transfer-agents 0 (refused)", ["report", "--transfer-agents", "0"], 2),
    ("coadapt export --format parket (refused)", ["export", "-o", "x", "--format", "parket"], 2),
    (
        "coadapt robot show kuafu --design abc (refused)",
        ["robot", "show", "kuafu", "--design", "abc"],
        2,
    ),
    ("coadapt robot show nope (refused)", ["robot", "show", "nope"], 2),
)
#: commands that do their work (build a model: numpy; a spec robot's standing pose: torch;
#: check it: Pinocchio and MuJoCo), timed with `--work`; no start-up goal applies to them
WORK = (
    ("coadapt robot show kuafu --no-validate", ["robot", "show", "kuafu", "--no-validate"], 0),
    ("coadapt robot show kuafu", ["robot", "show", "kuafu"], 0),
    ("coadapt robot show nezha", ["robot", "show", "nezha"], 0),
)

#: the libraries whose loading the table names
WATCHED = ("torch", "numpy", "pydantic")
CEILINGS = (
    ("python -c pass", ["-c", "pass"]),
    ("python -c 'import typer'", ["-c", "import typer"]),
)


def child_env(cold: bool) -> dict[str, str]:
    """The environment of the timed processes: bytecode cached (`.pyc` files under a folder
    of the temporary directory, not the checkout; one untimed run writes them first), as an
    installed copy has it, unless `cold` (every module compiled from source in every run, as
    under PYTHONDONTWRITEBYTECODE=1: up to 0.13 s more per command here)."""
    env = {**os.environ, "COLUMNS": "80"}
    if cold:
        return {**env, "PYTHONDONTWRITEBYTECODE": "1"}
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env.setdefault("PYTHONPYCACHEPREFIX", os.path.join(tempfile.gettempdir(), "cli_startup_pyc"))
    return env


def _time(args: list[str], expected: int | None, repeat: int, env: dict[str, str]) -> dict:
    """Median wall-clock seconds of `python args` over `repeat` fresh processes (after one
    untimed run), and whether torch was imported (one extra run with -X importtime)."""
    subprocess.run([sys.executable, *args], capture_output=True, env=env, check=False)
    seconds, cpu = [], []
    for _ in range(repeat):
        used = _children_cpu()
        start = time.perf_counter()
        done = subprocess.run([sys.executable, *args], capture_output=True, env=env, check=False)
        seconds.append(time.perf_counter() - start)
        cpu.append(_children_cpu() - used)
        if expected is not None and done.returncode != expected:
            raise SystemExit(
                f"{' '.join(args)} exited {done.returncode}, not {expected}: "
                + done.stderr.decode()[-500:]
            )
    traced = subprocess.run(
        [sys.executable, "-X", "importtime", *args], capture_output=True, env=env, check=False
    )
    profile = import_profile(traced.stderr.decode())
    return {
        "seconds": round(statistics.median(seconds), 3),
        "min_seconds": round(min(seconds), 3),
        "cpu_seconds": round(statistics.median(cpu), 3),
        "imports_torch": "torch" in profile["loaded"],
        "loads": [name for name in WATCHED if name in profile["loaded"]],
        "top_imports": profile["top"],
        "first_line": next(iter((done.stdout or done.stderr).decode().splitlines()), "")[:100],
    }


def _children_cpu() -> float:
    """CPU seconds (user + system) of this process's finished children so far."""
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    return used.ru_utime + used.ru_stime


def import_profile(trace: str, top: int = 5) -> dict:
    """From `python -X importtime`'s report (stderr): every module loaded, and the `top`
    modules imported at the top level (not by another module) with the largest cumulative
    time, as [name, seconds]."""
    loaded, outer = set(), []
    for line in trace.splitlines():
        if not line.startswith("import time:") or line.count("|") != 2:
            continue
        _, cumulative, name = line.split("|")
        if not cumulative.strip().isdigit():  # the header line
            continue
        loaded.add(name.strip())
        if len(name) - len(name.lstrip()) <= 1:  # one space after the bar: top level
            outer.append((int(cumulative) / 1e6, name.strip()))
    outer.sort(reverse=True)
    return {"loaded": loaded, "top": [[name, round(s, 3)] for s, name in outer[:top]]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5, help="fresh processes per command")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--work", action="store_true", help="also time commands that do their work (WORK)"
    )
    parser.add_argument(
        "--cold", action="store_true", help="no bytecode cache: compile every module every run"
    )
    args = parser.parse_args(argv)
    env = child_env(args.cold)
    out = {
        "repeat": args.repeat,
        "cpus": os.cpu_count(),
        "load_average": [round(x, 2) for x in os.getloadavg()],
        "bytecode": "compiled every run" if args.cold else "cached",
        "ceilings": {label: _time(a, 0, args.repeat, env) for label, a in CEILINGS},
        "commands": {
            label: _time(["-m", "coadapt_core", *a], code, args.repeat, env)
            for label, a, code in COMMANDS
        },
    }
    if args.work:
        out["work"] = {
            label: _time(["-m", "coadapt_core", *a], code, args.repeat, env)
            for label, a, code in WORK
        }
    typer_s = out["ceilings"]["python -c 'import typer'"]["seconds"]
    for r in out["commands"].values():
        r["within_2x_typer"] = r["seconds"] <= 2 * typer_s
        r["within_0_3_s"] = r["seconds"] <= 0.3
        r["cpu_within_0_3_s"] = r["cpu_seconds"] <= 0.3
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(f"{'command':50} {'median s':>8} {'min s':>6} {'cpu s':>6} {'<=2x typer':>10}  loads")
    for group in ("ceilings", "commands", "work"):
        for label, r in out.get(group, {}).items():
            within = "yes" if r.get("within_2x_typer") else "no" if group == "commands" else ""
            loads = ", ".join(r["loads"]) or "-"
            print(
                f"{label:50} {r['seconds']:8.3f} {r['min_seconds']:6.3f} {r['cpu_seconds']:6.3f} "
                f"{within:>10}  {loads}"
            )
            top = "  ".join(f"{name} {s:.3f}" for name, s in r["top_imports"])
            print(f"{'':4}imports (cumulative s): {top}")
    print(
        f"load average {out['load_average']} on {out['cpus']} CPUs, {args.repeat} runs each, "
        f"bytecode {out['bytecode']}; "
        f"2x import typer = {2 * typer_s:.3f} s"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
