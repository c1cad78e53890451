"""Helpers shared by the CLI commands: plugins by name, one-line user errors, Ctrl-C, and
`run_app`, which runs the app (the options: `coadapt_core.cli.options`; their help:
`coadapt_core.cli.help`)."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from typing import Any, NoReturn

import typer

from coadapt_core.cli.help import plain_help
from coadapt_core.errors import CoadaptError, PluginError, UnknownPluginError, UserError

#: exit code for bad input (usage errors, bad config, unknown plugin names)
EXIT_USAGE = 2


def fail(message: str, code: int = EXIT_USAGE) -> NoReturn:
    """Print one line to stderr and exit."""
    print(f"error: {message}", file=sys.stderr)
    raise typer.Exit(code)


def wide_console(*renderables: Any, stream: Any = None) -> Any:
    """A rich console for `renderables` (tables): on a terminal its width (or $COLUMNS when
    set), where a table too wide folds its cells; in a pipe or a file without $COLUMNS at
    least the widest renderable's natural width (never under 80), so no column is cut or
    folded and a log keeps every column."""
    import os

    from rich.console import Console

    console = Console(file=stream)
    if console.is_terminal or os.environ.get("COLUMNS", "").strip().isdigit():
        return console
    unbounded = console.options.update_width(10_000)
    widest = max((console.measure(r, options=unbounded).maximum for r in renderables), default=0)
    return Console(file=stream, width=max(console.width, widest))


def one_line(text: object) -> str:
    """`text` on one line (whitespace runs, newlines included, become one space)."""
    return " ".join(str(text).split())


def os_error_line(exc: OSError) -> str:
    """One line for an error of the file system (full disk, read-only or missing folder, a
    file where a folder is expected), naming the path and what would work."""
    import errno
    import os

    # some libraries (TensorBoard's writer) pass the path as bytes: shown as text all the same
    where = f"'{os.fsdecode(exc.filename)}'" if exc.filename else "a file"
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return (
            f"disk full writing {where}; free some space and run the command again "
            "(nothing partial was kept)"
        )
    if exc.errno in (errno.EROFS, errno.EACCES, errno.EPERM):
        return f"cannot write {where} ({exc.strerror}); give a folder you can write to (--out / -o)"
    if exc.errno in (errno.EEXIST, errno.ENOTDIR):
        return f"{where} is a file where a folder is needed; give a folder path (--out / -o)"
    if exc.errno == errno.EISDIR:
        return f"{where} is a folder where a file is needed"
    if exc.errno == errno.ENOENT:
        return f"{where} does not exist"
    return f"{exc.strerror or type(exc).__name__}: {where}"


#: exit code of a command stopped by Ctrl-C (128 + SIGINT, as a shell reports it)
EXIT_INTERRUPTED = 130


@contextlib.contextmanager
def ctrl_c_once() -> Iterator[None]:
    """Within: the first Ctrl-C (SIGINT) raises KeyboardInterrupt where the command is, and
    later ones are ignored while it records where it stopped and says how to resume (a
    second Ctrl-C used to cut that short). The previous handler is restored on exit."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.getsignal(signal.SIGINT)

    def handler(signum: int, frame: Any) -> None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def interrupted(what: str, resume: str | None) -> NoReturn:
    """After Ctrl-C: one line saying what stopped and the exact command that continues it
    (or that nothing can be continued), then exit 130."""
    if resume:
        print(f"\ninterrupted: {what}; continue it with: {resume}", file=sys.stderr, flush=True)
    else:
        print(f"\ninterrupted: {what}", file=sys.stderr, flush=True)
    raise typer.Exit(EXIT_INTERRUPTED)


def invocation() -> list[str]:
    """The arguments of the command being run (after `coadapt`), as `run_app` was given them."""
    return list(_INVOCATION)


_INVOCATION: list[str] = []


def plugin_name(kind: str, given: str | None) -> str:
    """`given`, or the installed plugin of `kind` with the highest `default_rank` (one-line
    error when none is installed)."""
    if given:
        return given
    from coadapt_core.plugins import get_registry

    try:
        return get_registry().default(kind)
    except UnknownPluginError as exc:
        fail(str(exc))


def resolve(kind: str, name: str) -> type:
    """The plugin class for `name`, or a one-line error listing what is available."""
    from coadapt_core.plugins import get_registry

    try:
        return get_registry().get(kind, name)
    except UnknownPluginError as exc:
        fail(str(exc))


def simulator_for(sim: str, terrain: str) -> type:
    """The simulator plugin class `sim`, checked to build `terrain` (one line, exit 2)."""
    cls = resolve("simulator", sim)
    if terrain not in cls.terrains:
        fail(
            f"--terrain '{terrain}' is not supported by simulator '{sim}'; "
            f"one of: {', '.join(cls.terrains)}"
        )
    return cls


def check_device_option(device: str) -> None:
    """--device: a device torch knows, and CUDA only where torch sees it (one line, exit 2)."""
    import torch

    from coadapt_core.coadapt.config import check_device

    try:
        check_device(device, field="--device")
    except UserError as exc:
        fail(str(exc))
    if device.startswith("cuda") and not torch.cuda.is_available():
        fail("--device cuda requested but torch sees no CUDA device; use --device cpu")


def run_app(app: typer.Typer, argv: list[str] | None = None) -> int:
    """Run the `coadapt` app (or a command of it) on `argv`; user errors become one line on
    stderr and exit code 2 (`coadapt_core.cli.main`, and `coadapt grid`'s check of its cells)."""
    outer = list(_INVOCATION)  # `coadapt grid` checks its cells' command lines with run_app
    _INVOCATION[:] = list(sys.argv[1:] if argv is None else argv)  # before the commands are made
    try:
        return _run_command(app, argv)
    finally:  # a command made later (the tests, the settings docs) has all its options
        _INVOCATION[:] = outer


def _run_command(app: typer.Typer, argv: list[str] | None) -> int:
    """`run_app` once the command line is known: its command made, run, its errors said."""
    command = typer.main.get_command(app)
    plain_help(command)
    try:
        result = command.main(args=argv, prog_name="coadapt", standalone_mode=False)
    except typer.Exit as exc:
        return exc.exit_code
    except typer.Abort:
        print("aborted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except typer.TyperException as exc:  # usage errors: bad option, missing argument, ...
        ctx = getattr(exc, "ctx", None)
        if type(exc).__name__ == "NoArgsIsHelpError" and ctx is not None:
            print(ctx.get_help(), file=sys.stderr)
            return EXIT_USAGE
        where = f" ({ctx.command_path})" if ctx is not None else ""
        message = exc.format_message() if hasattr(exc, "format_message") else str(exc)
        print(f"error: {one_line(message)}{where}", file=sys.stderr)  # every error starts `error:`
        return int(getattr(exc, "exit_code", EXIT_USAGE) or EXIT_USAGE)
    except (UserError, PluginError) as exc:
        print(f"error: {one_line(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except CoadaptError as exc:
        print(f"error: {one_line(exc)}", file=sys.stderr)
        return 1
    except (
        OSError
    ) as exc:  # the file system said no: full disk, read-only folder, a file for a folder
        print(f"error: {os_error_line(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except Exception as exc:
        if type(exc).__module__.split(".")[0] != "sqlalchemy":
            raise
        # the results store failed under a command (damaged, emptied, locked, unreachable)
        detail = one_line(getattr(exc, "orig", None) or exc)[:200]
        print(
            f"error: the results store failed ({detail}); check --store / $COADAPT_STORE, or "
            "move a damaged store aside and resume the runs (`coadapt run --resume`) to record "
            "them again",
            file=sys.stderr,
        )
        return EXIT_USAGE
    return result if isinstance(result, int) else 0
