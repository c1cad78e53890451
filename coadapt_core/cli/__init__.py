"""The `coadapt` command line. Each command lives in its own module of this package; option
choices for plugins (`--robot`, `--sim`, `--optimizer`, `--objective`) come from the
registry, so a third-party plugin shows up in `--help` and in error messages.

Commands are registered lazily. `COMMANDS` below names each command, the module of this
package that declares it (its `register(app)` adds the command to a typer app, as before) and
the one line `coadapt --help` shows for it; `coadapt --help`, and the refusal of an unknown
command, read that table and import no command module. A command's module, and what it
imports (its settings classes, pydantic's models of `coadapt run`'s settings, numpy, the
plugins), is imported only when that command runs or its own `--help` is asked for
(`LazyGroup`). Adding a command: a module with `register(app)` and one `Command` line in
`COMMANDS` (tests/test_cli_startup.py checks that each line says what the command's own
docstring says, and the options of every command: `coadapt_core.cli.common_options`).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import typer
from typer.core import TyperGroup


@dataclass(frozen=True)
class Command:
    """One command of `coadapt`: its module under `coadapt_core.cli` (whose `register(app)`
    makes it), its line in `coadapt --help`, and what it does: `simulates` (steps a physics
    engine: it takes `--threads`), `progress` (draws a progress line: it takes `--quiet`)."""

    module: str
    help: str
    simulates: bool = False
    progress: bool = False


#: every command, in the order `coadapt --help` lists them
COMMANDS: dict[str, Command] = {
    "run": Command(
        "run",
        "Co-adapt design and policy: universal policy + pseudo-critics, optimizer with hybrid "
        "real/surrogate fitness, range narrowing (paper Algorithm 4).",
        simulates=True,
        progress=True,
    ),
    "plugins": Command(
        "plugins",
        "List the robots, simulators, optimizers and objectives that are installed, with the "
        "plugin API version each was written for (this coadapt's is shown in the title).",
    ),
    "train": Command(
        "train",
        "Train the universal policy pi(a|o, xi) with its critic and pseudo-critics (PPO).",
        simulates=True,
        progress=True,
    ),
    "eval": Command(
        "evaluate",
        "Roll out a policy on one design and report survival, speed and costs.",
        simulates=True,
        progress=True,
    ),
    "grid": Command(
        "grid",
        "Run an ablation grid locally or on a Ray cluster, skipping cells the store holds as "
        "finished and resuming cells a killed grid left unfinished.",
        simulates=True,
        progress=True,
    ),
    "report": Command(
        "report",
        "Write tables (Markdown, CSV) and figures (PNG, HTML) from a run or grid.",
        simulates=True,
        progress=True,
    ),
    "export": Command(
        "export",
        "Write runs, evaluations, training phases, checkpoints and verifications, one file per "
        "table.",
    ),
    "import": Command(
        "importing",
        "Merge exported runs into a store: new runs are added, a run already there is replaced "
        "only by a copy further along (finished, or updated later).",
    ),
    "landscape": Command(
        "landscape",
        "Evaluate the real cost (Algorithm 2) of a grid over the robot's first two design "
        "variables (Kuafu: thigh and shank scale) with the universal policy; reports draw it as "
        "a heat-map and mark each method's optimum.",
        simulates=True,
        progress=True,
    ),
    "handoff": Command(
        "handoff",
        "Write the design's URDF and MJCF, its controller as ONNX (checked against torch), "
        "policy.json, the design sheet (design.md, design.json), the GIF, a README and "
        "check.py.",
        simulates=True,
        progress=True,
    ),
    "dashboard": Command(
        "dashboard",
        "Serve a live, read-only web view of the runs, a run, a grid and a comparison.",
    ),
    "robot": Command("robot", "Inspect, export, validate and render robot designs."),
    "verify": Command(
        "verify",
        "Fine-tune a specialist policy at the run's best design and one at the nominal design "
        "from its universal policy (same budget, same seed), repeat its paired final check with "
        "each design driven by its own specialist, and say whether the answer holds, shrinks, "
        "grows or does not hold.",
        simulates=True,
        progress=True,
    ),
}


#: command name -> the typer app its module registered it on (once per process)
_REGISTERED: dict[str, typer.Typer] = {}


def make_command(name: str) -> Any:
    """The click command of `coadapt NAME`: its module imported and its `register(app)` run
    on an app of its own, once (its options from its settings classes, `cli/options.py`);
    the command made from it each time (a command's options may depend on the command line,
    `options.LateGroup`), laid out as every command's help is (`cli/help.py`)."""
    import importlib

    from coadapt_core.cli.help import RUN_COMMON_OPTIONS, plain_help, short_help

    if name not in _REGISTERED:
        declare_root()  # pydantic is loaded with the command's settings classes anyway
        module = importlib.import_module(f"coadapt_core.cli.{COMMANDS[name].module}")
        own = typer.Typer(add_completion=False, pretty_exceptions_enable=False)
        module.register(own)
        _REGISTERED[name] = own
    command = typer.main.get_group(_REGISTERED[name]).commands[name]
    plain_help(command)
    if name == "run":  # `coadapt run --help` lists the common options, --help-all every one
        short_help(command, RUN_COMMON_OPTIONS)
    return command


class LazyCommands(Mapping):
    """The commands of `coadapt` by name, each made (`make_command`) when first looked up:
    listing the names, or asking whether one exists, makes none."""

    def __init__(self) -> None:
        self.made: dict[str, Any] = {}

    def __getitem__(self, name: str) -> Any:
        if name not in COMMANDS:
            raise KeyError(name)
        if name not in self.made:
            self.made[name] = make_command(name)
        return self.made[name]

    def __iter__(self) -> Iterator[str]:
        return iter(COMMANDS)

    def __len__(self) -> int:
        return len(COMMANDS)

    def __contains__(self, name: object) -> bool:
        return name in COMMANDS


class LazyGroup(TyperGroup):
    """`coadapt` itself: its commands made on first use (`LazyCommands`), its help listing
    them from `COMMANDS` without making any."""

    def __init__(self, **attrs: Any) -> None:
        attrs.pop("commands", None)
        super().__init__(**attrs)
        self.commands = LazyCommands()  # type: ignore[assignment]

    def add_command(self, cmd: Any, name: str | None = None) -> None:
        raise TypeError("coadapt's commands are listed in coadapt_core.cli.COMMANDS")

    def list_commands(self, ctx: Any) -> list[str]:
        return list(COMMANDS)

    def format_commands(self, ctx: Any, formatter: Any) -> None:
        from typer._click.utils import make_default_short_help

        limit = formatter.width - 6 - max(len(name) for name in COMMANDS)
        rows = [(name, make_default_short_help(c.help, limit)) for name, c in COMMANDS.items()]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


app = typer.Typer(
    name="coadapt",
    help="Co-adapt a robot's design and its locomotion policy (Du et al. 2025).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    cls=LazyGroup,
)


def _root(**values: Any) -> None:
    """Co-adapt a robot's design and its locomotion policy."""


def _root_options() -> Any:
    """`coadapt`'s own options, as `RootOptions` declares them (`cli/common_options.py`), made
    without pydantic (`options.EarlySwitch`): `coadapt --help` and `--version` cost typer."""
    from coadapt_core.cli.options import EarlySwitch, bind
    from coadapt_core.cli.version import print_version

    return bind(_root, [EarlySwitch("version", "--version", "Print the version.", print_version)])


def declare_root() -> None:
    """Record `coadapt`'s own options from their declaration (`RootOptions`) in
    `options.DECLARED`, as every command's are when it is made (docs/settings.md, the tests)."""
    from coadapt_core.cli.common_options import RootOptions
    from coadapt_core.cli.options import DECLARED, options_of

    if "" not in DECLARED:
        DECLARED[""] = (options_of(RootOptions),)


def load_all() -> dict[str, Any]:
    """Every command made (the settings docs and the tests read them all): name -> command."""
    group = typer.main.get_command(app)
    return {name: group.commands[name] for name in COMMANDS}


def main(argv: list[str] | None = None) -> int:
    """Entry point: runs the app and turns user errors into one line and exit code 2."""
    from coadapt_core.cli.common import run_app

    return run_app(app, argv)


app.callback()(_root_options())
