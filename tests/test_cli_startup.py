"""The command line answers without loading torch or a plugin where it needs neither (issue 50):
`coadapt --help`, a command's `--help` page and the refusal of a typo in a choice; and
`coadapt plugins` loads every plugin without torch or a physics engine, listing what it listed
when they imported torch. Checked in a fresh interpreter through `sys.modules`, not by timing
(benchmarks/cli_startup.py times the commands); a refused choice names the nearest accepted
value."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import make_dist

PROBE = """
import contextlib, io, json, sys
from coadapt_core.cli import main
err = io.StringIO()
with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.redirect_stderr(err):
    code = main(sys.argv[1:])
heavy = sorted(m for m in ("torch", "mujoco", "pybullet", "ray", "matplotlib", "sqlalchemy",
                           "coadapt_plugins") if m in sys.modules)
print(json.dumps({"code": code, "heavy": heavy, "out": out.getvalue(), "err": err.getvalue()}))
"""


def _probe(*args: str, preload: str = "", pythonpath: Path | None = None) -> dict:
    """`coadapt ARGS` in a fresh interpreter (after `import PRELOAD` when given): its exit
    status, the heavy modules loaded by then, its output."""
    env = {k: v for k, v in os.environ.items() if k != "COADAPT_LOAD_PLUGINS"}
    if pythonpath is not None:
        env["PYTHONPATH"] = str(pythonpath)
    code = (f"import {preload}\n" if preload else "") + PROBE
    done = subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=120, env=env
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


#: pydantic's models of `coadapt run`'s settings: its config tree and the learner's sections
RUN_SETTINGS = (
    "coadapt_core.coadapt.config",
    "coadapt_core.coadapt.learner_overrides",
    "coadapt_core.learning.config",
)

#: what `coadapt --help`, a command's --help and a refusal load (issue 61): never torch nor
#: the run's settings; no numpy either, but where the command lists the plugins (their
#: modules import it) or takes `coadapt run`'s settings
LOADED = """
import contextlib, io, json, sys
from coadapt_core.cli import main
with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as err:
    code = main(sys.argv[1:])
watched = ("numpy", "torch", "pydantic", "coadapt_plugins", *RUN_SETTINGS)
print(json.dumps({"code": code, "err": err.getvalue(),
                  "loaded": sorted(m for m in watched if m in sys.modules)}))
"""


def _loaded(*args: str) -> dict:
    """`coadapt ARGS` in a fresh interpreter: its exit status, stderr and which of the watched
    modules it loaded."""
    code = f"RUN_SETTINGS = {RUN_SETTINGS!r}\n" + LOADED
    done = subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize(
    ("args", "code"),
    [
        (["--help"], 0),
        (["--version"], 0),
        (["runn"], 2),  # an unknown command: "did you mean 'run'?"
        (["report", "--help"], 0),
        (["export", "--help"], 0),
        (["import", "--help"], 0),
        (["plugins", "--help"], 0),
        (["handoff", "--help"], 0),
        (["dashboard", "--help"], 0),
        (["export", "-o", "x", "--format", "parket"], 2),
        (["report", "--transfer-agents", "0"], 2),
        (["import", "x", "--formt", "csv"], 2),  # "no such option", did you mean --format
        (["handoff", "x", "--threads", "0"], 2),
    ],
)
def test_help_and_refusals_load_neither_numpy_nor_the_run_settings_nor_torch(args, code):
    result = _loaded(*args)
    assert result["code"] == code, result["err"]
    assert [m for m in result["loaded"] if m != "pydantic"] == [], result["loaded"]


@pytest.mark.parametrize("args", [["--help"], ["--version"], []])
def test_top_level_help_and_version_load_not_even_pydantic(args):
    """`coadapt` itself answers with typer alone: its `--version` is made without its settings
    class (`options.EarlySwitch`), the commands are listed from `COMMANDS`. (Any command line
    typer reads values from loads pydantic: typer converts every value with it.)"""
    result = _loaded(*args)
    assert result["code"] == (0 if args else 2)
    assert result["loaded"] == [], result["loaded"]


def test_top_level_help_and_an_unknown_command_load_no_command_module():
    """`coadapt --help` lists the commands from `coadapt_core.cli.COMMANDS`: no command module
    is imported, so neither are their settings classes."""
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from coadapt_core.cli import main, COMMANDS; main(['--help']); "
            "main(['runn']); own = {f'coadapt_core.cli.{c.module}' for c in COMMANDS.values()}; "
            "print(sorted(own & set(sys.modules)))",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == "[]"


#: command lines answered from the command line and the installed plugins alone (issue 61):
#: listing the plugins, `coadapt run --help`, a refused value of `coadapt run` (a plugin name,
#: the preset, --verify-budget) and of `coadapt robot show` (an unknown robot, a --design that
#: is no numbers). They may load the plugin modules (the registry lists them), never numpy,
#: torch nor pydantic's models of `coadapt run`'s settings: those load when a run goes.
LIGHT = [
    (["plugins"], 0),
    (["plugins", "--json"], 0),
    (["run", "--help"], 0),
    (["run", "--help-all"], 0),
    (["run", "--optimizer", "nope"], 2),
    (["run", "--inertia", "0.5", "--optimizer", "nope"], 2),  # a plugin's alias is made
    (["run", "--sim", "mujocoo"], 2),
    (["run", "--objective", "power,torq"], 2),
    (["run", "--robot", "kuafuu"], 2),
    (["run", "--preset", "smok"], 2),
    (["run", "--verify-budget", "0"], 2),
    (["run", "--threads", "0"], 2),
    (["robot", "--help"], 0),
    (["robot", "show", "--help"], 0),
    (["robot", "show", "nope"], 2),
    (["robot", "show", "kuafu", "--design", "abc"], 2),
    (["robot", "show", "kuafu", "--design", "1,2,3"], 2),
]


@pytest.mark.parametrize(("args", "code"), LIGHT, ids=[" ".join(a) for a, _ in LIGHT])
def test_plugins_run_help_and_refusals_load_neither_numpy_nor_the_run_settings_nor_torch(
    args, code
):
    result = _loaded(*args)
    assert result["code"] == code, result["err"]
    assert not {"numpy", "torch", *RUN_SETTINGS} & set(result["loaded"]), result["loaded"]
    if code == 2:
        assert len(result["err"].strip().splitlines()) == 1, result["err"]


#: modules a refusal of one plugin kind never loads (issue 61): the registry asks only the kind
#: named (no robot's module for a simulator, no simulator's for a robot), and the shipped spec
#: robots are listed by their folders' names (no spec read: neither YAML nor the spec reader)
ROBOTS = ("coadapt_plugins.robots.kuafu.robot", "coadapt_plugins.robots.specs.robot")
SPECS_READ = ("yaml", "coadapt_plugins.robots.specs.spec")
SIMULATORS = (
    "coadapt_core.physics.simulator",
    "coadapt_core.physics.randomization",  # its settings class (a pydantic dataclass)
    "coadapt_plugins.simulators.mujoco.simulator",
    "coadapt_plugins.simulators.pybullet.simulator",
)
KIND_ONLY = [
    (["run", "--sim", "mujocoo"], (*ROBOTS, *SPECS_READ)),
    (["run", "--optimizer", "nope"], (*ROBOTS, *SPECS_READ, *SIMULATORS)),
    (["robot", "show", "nope"], (*SPECS_READ, *SIMULATORS)),
    (["robot", "show", "kuafu", "--design", "abc"], (*SPECS_READ, *SIMULATORS)),
    (["run", "--help"], SPECS_READ),
]


@pytest.mark.parametrize(("args", "absent"), KIND_ONLY, ids=[" ".join(a) for a, _ in KIND_ONLY])
def test_a_refusal_loads_the_plugins_of_the_kind_it_names_alone(args, absent):
    code = (
        "import contextlib, io, json, sys\n"
        "from coadapt_core.cli import main\n"
        "with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):"
        "\n    code = main(sys.argv[1:])\n"
        f"print(json.dumps([code, sorted(m for m in {absent!r} if m in sys.modules)]))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert json.loads(done.stdout.strip().splitlines()[-1]) == [
        2 if "--help" not in args else 0,
        [],
    ]


def test_the_plugins_listed_and_a_refusal_load_the_plugins_themselves():
    """The light answers above still read the installed plugins: `coadapt plugins` imports
    every plugin's module (the check would pass vacuously if the registry stayed unloaded)."""
    assert "coadapt_plugins" in _loaded("plugins")["loaded"]
    refused = _loaded("run", "--optimizer", "nope")
    assert "coadapt_plugins" in refused["loaded"] and "unknown optimizer" in refused["err"]


@pytest.mark.parametrize("name", list(__import__("coadapt_core.cli").cli.COMMANDS))
def test_each_line_of_the_command_table_is_the_commands_own_help(name):
    """`coadapt --help` shows `COMMANDS`' line of each command without making it: the line is
    the command's own help (its docstring's first paragraph)."""
    from coadapt_core.cli import COMMANDS, make_command

    own = " ".join((make_command(name).help or "").split("\n\n")[0].split())
    assert COMMANDS[name].help == own


def test_every_command_module_is_in_the_command_table():
    """A module of coadapt_core/cli that registers a command (`def register(app`) is named by
    a line of `COMMANDS`: a command left out of the table would be unreachable."""
    from coadapt_core.cli import COMMANDS

    cli = Path(__file__).resolve().parents[1] / "coadapt_core" / "cli"
    registering = {
        path.stem
        for path in cli.glob("*.py")
        if re.search(r"^def register\(\w+: typer\.Typer\)", path.read_text(), re.M)
    }
    assert registering == {c.module for c in COMMANDS.values()}


def test_importing_the_cli_loads_neither_torch_nor_a_plugin():
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys, coadapt_core.cli; "
            "print(sorted(m for m in ('torch', 'mujoco', 'coadapt_plugins') if m in sys.modules))",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "[]"


@pytest.mark.parametrize("args", [["--help"], ["report", "--help"], ["export", "--help"]])
def test_help_pages_answer_without_torch_or_plugins(args):
    result = _probe(*args)
    assert result["code"] == 0 and result["heavy"] == []
    assert "Usage: coadapt" in result["out"]


def test_top_level_help_lists_every_command():
    out = _probe("--help")["out"]
    for command in ("run", "plugins", "report", "handoff", "export", "grid"):
        assert f"  {command} " in out, command


@pytest.mark.parametrize(
    ("args", "line"),
    [
        (
            ["run", "--preset", "smok"],
            "error: preset 'smok' is not one of smoke, quick, paper; did you mean 'smoke'?",
        ),
        (
            ["export", "-o", "x", "--format", "parket"],
            "error: format 'parket' is not one of csv, parquet; did you mean 'parquet'?",
        ),
        (
            ["report", "--transfer-agents", "0"],
            "error: --transfer-agents, --transfer-steps and --common-blocks must be >= 1",
        ),
    ],
)
def test_a_refusal_is_one_line_exit_2_without_torch(args, line):
    result = _probe(*args)
    assert result["code"] == 2 and result["err"].strip().splitlines() == [line]
    assert "torch" not in result["heavy"] and "coadapt_plugins" not in result["heavy"]


@pytest.mark.parametrize(
    ("args", "start", "end"),
    [
        (["run", "--sim", "mujocoo"], "error: unknown simulator 'mujocoo'", "'mujoco'?"),
        (["run", "--optimizer", "psoo"], "error: unknown optimizer 'psoo'", "'pso'?"),
        (["run", "--objective", "power,torq"], "error: unknown objective 'torq'", "'torque'?"),
    ],
)
def test_a_mistyped_plugin_name_is_refused_before_torch_loads(args, start, end):
    """The registry lists the plugins without torch, so `coadapt run` checks the names on its
    command line before it sets torch's threads (it took 2.3-2.7 s, torch's import)."""
    result = _probe(*args)
    lines = result["err"].strip().splitlines()
    assert result["code"] == 2 and len(lines) == 1, result["err"]
    assert lines[0].startswith(start) and lines[0].endswith(end), lines
    assert "torch" not in result["heavy"]


def test_run_help_all_still_lists_the_plugins_aliases():
    """`coadapt run --help-all` makes the aliases the installed plugins declare (the registry
    loads for it): --inertia is an alias of the PSO optimizer's option."""
    result = _probe("run", "--help-all")
    assert result["code"] == 0 and "--inertia" in result["out"]
    assert "coadapt_plugins" in result["heavy"]


#: the built-in plugins `coadapt plugins` lists (a robot found in a user's folder may add one)
BUILT_IN = {
    "simulator": ["mujoco", "pybullet"],
    "optimizer": ["bo", "gradient", "mixed-pso", "nsga2", "pso"],
    "objective": ["composite", "power", "torque", "tracking"],
}


def _listing(result: dict) -> dict:
    assert result["code"] == 0, result["err"]
    return json.loads(result["out"])


def test_plugins_lists_every_plugin_without_torch_or_an_engine():
    """Listing loads the plugin modules (their classes, names, versions, options) but neither
    torch nor MuJoCo nor PyBullet: a simulator class reads `dtype` only when asked."""
    result = _probe("plugins", "--json")
    assert result["heavy"] == ["coadapt_plugins"]
    listing = _listing(result)
    names = {kind: [p["name"] for p in found] for kind, found in listing["plugins"].items()}
    for kind, expected in BUILT_IN.items():
        assert names[kind] == expected, kind
    assert {"kuafu", "nezha", "qilin"} <= set(names["robot"])
    assert listing["broken"] == []


def test_plugins_lists_the_same_with_torch_loaded_first():
    """What the listing says does not depend on torch being loaded: the JSON of a process
    that imported torch first (as every plugin module did before) is the same."""
    lazy = _listing(_probe("plugins", "--json"))
    loaded = _probe("plugins", "--json", preload="torch")
    assert "torch" in loaded["heavy"]
    assert _listing(loaded) == lazy


TORCH_AT_TOP = """
import torch

from coadapt_core import hookimpl
from coadapt_core.physics.simulator import Simulator

COADAPT_PLUGIN_API = "2.2"


class EagerSimulator(Simulator):
    name = "eager"
    description = "imports torch with its module"
    dtype = torch.float32


@hookimpl
def coadapt_register_simulators():
    return [EagerSimulator]
"""


def test_a_plugin_that_imports_torch_at_its_top_still_loads(tmp_path):
    """A third-party simulator may import torch with its module and set a plain dtype: it is
    listed beside the built-ins (that listing just loads torch), its dtype its own."""
    site = make_dist(
        tmp_path / "site",
        "eager-sim",
        "[coadapt]\neager-sim = eager_sim\n",
        {"eager_sim": TORCH_AT_TOP},
    )
    result = _probe("plugins", "--json", pythonpath=site)
    assert "torch" in result["heavy"]
    listing = _listing(result)
    simulators = {p["name"]: p for p in listing["plugins"]["simulator"]}
    assert list(simulators) == ["eager", "mujoco", "pybullet"]
    assert simulators["eager"]["distribution"] == "eager-sim"
    check = subprocess.run(
        [
            sys.executable,
            "-c",
            "import torch, eager_sim; from coadapt_core.physics.simulator import Simulator; "
            "print(eager_sim.EagerSimulator.dtype is torch.float32, "
            "Simulator.dtype is torch.float64)",
        ],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "PYTHONPATH": str(site)},
    )
    assert check.stdout.split() == ["True", "True"], check.stderr[-2000:]
