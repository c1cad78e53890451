"""The options several commands share, each declared once here (`CommonOptions`), and the
options of `coadapt` itself (`RootOptions`).

A command takes a common option as it is, with `shared` in its settings class::

    threads: Any = shared(CommonOptions)
    quiet: Any = shared(CommonOptions)

(`shared(CommonOptions, default=...)` where its default differs). Which commands must take
which: `coadapt_core.cli.COMMANDS` says which commands step a physics engine (they take
`--threads`) and which draw a progress line (they take `--quiet`); tests/test_cli_startup.py
reads every command's options from the app and checks them against it. `coadapt run`'s
`--seed` and `--store` are settings of its config (`CoadaptConfig`: YAML keys too, with the
run's own meaning of an empty store), the others' come from here.

Nothing here imports torch, numpy or the config tree: the commands that declare their options
with these answer their `--help` and refusals without them.
"""

from __future__ import annotations

from coadapt_core.cli.version import print_version
from coadapt_core.settings import Int, setting, settings


@settings
class CommonOptions:
    """The options several commands share: `--threads` (every command that simulates),
    `--quiet` (every command with a progress line), `--json`, `--store` (every command that
    reads or writes a results store) and `--seed`."""

    threads: Int | None = setting(
        None,
        "CPU threads of the physics and of torch (default: the CPUs this process may use, "
        "its affinity mask and cgroup CPU quota; never the checkpoint's).",
        ge=1,
    )
    quiet: bool = setting(
        False,
        "No progress line on stderr; results, warnings and errors print as usual (`coadapt "
        "train`: one JSON line per iteration on stdout instead).",
    )
    as_json: bool = setting(
        False,
        "Print the result as JSON on stdout: in place of tables, or as the last line after "
        "the command's other output.",
        names=("--json",),
    )
    store: str | None = setting(
        None, "Results store: a path or SQLAlchemy URL (default: $COADAPT_STORE or ./coadapt.db)."
    )
    seed: Int = setting(0, "Random seed.", ge=0)


@settings
class RootOptions:
    """The options of `coadapt` itself, before a command (the option is made without pydantic,
    from the same words: `coadapt_core.cli.options.EarlySwitch`)."""

    version: bool = setting(
        False, "Print the version.", names=("--version",), callback=print_version
    )


__all__ = ["CommonOptions", "RootOptions"]
