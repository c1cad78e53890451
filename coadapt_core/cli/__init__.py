"""The `coadapt` command line. Each command lives in its own module of this package; option
choices for plugins (`--robot`, `--sim`, `--optimizer`, `--objective`) come from the
registry, so a third-party plugin shows up in `--help` and in error messages."""

from __future__ import annotations

import sys

import typer

from coadapt_core import __version__
from coadapt_core.cli import export, grid, landscape, plugins, report, robot, run, train
from coadapt_core.cli.common import EXIT_USAGE, one_line, os_error_line, style_help
from coadapt_core.errors import CoadaptError, PluginError, UserError

app = typer.Typer(
    name="coadapt",
    help="Co-adapt a robot's design and its locomotion policy (Du et al. 2025).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _version(value: bool) -> None:
    if value:
        print(f"coadapt {__version__}")
        raise typer.Exit(0)


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, help="Print the version."),
) -> None:
    """Co-adapt a robot's design and its locomotion policy."""


run.register(app)
plugins.register(app)
app.add_typer(robot.app, name="robot")
train.register(app)
grid.register(app)
report.register(app)
export.register(app)
landscape.register(app)


def main(argv: list[str] | None = None) -> int:
    """Entry point: runs the app and turns user errors into one line and exit code 2."""
    command = typer.main.get_command(app)
    style_help(command)
    try:
        result = command.main(args=argv, prog_name="coadapt", standalone_mode=False)
    except typer.Exit as exc:
        return exc.exit_code
    except typer.Abort:
        print("aborted", file=sys.stderr)
        return 130
    except typer.TyperException as exc:  # usage errors: bad option, missing argument, ...
        ctx = getattr(exc, "ctx", None)
        if type(exc).__name__ == "NoArgsIsHelpError" and ctx is not None:
            print(ctx.get_help(), file=sys.stderr)
            return EXIT_USAGE
        where = f" ({ctx.command_path})" if ctx is not None else ""
        message = exc.format_message() if hasattr(exc, "format_message") else str(exc)
        print(f"error{where}: {message}", file=sys.stderr)
        return int(getattr(exc, "exit_code", EXIT_USAGE) or EXIT_USAGE)
    except (UserError, PluginError) as exc:
        print(f"error: {one_line(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except CoadaptError as exc:
        print(f"error: {one_line(exc)}", file=sys.stderr)
        return 1
    except OSError as exc:  # the file system said no: full disk, read-only folder, a file for a folder
        print(f"error: {os_error_line(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except Exception as exc:
        if type(exc).__module__.split(".")[0] != "sqlalchemy":
            raise
        # the results store failed under a command (damaged, emptied, locked, unreachable)
        detail = one_line(getattr(exc, "orig", None) or exc)[:200]
        print(f"error: the results store failed ({detail}); check --store / $COADAPT_STORE, or move a damaged "
              "store aside and resume the runs (`coadapt run --resume`) to record them again", file=sys.stderr)
        return EXIT_USAGE
    return result if isinstance(result, int) else 0


def entry() -> None:  # pragma: no cover - console script
    sys.exit(main())
