"""Helpers shared by the CLI commands: plugins by name, one-line user errors, one help style
(the options themselves: `coadapt_core.cli.options`)."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from typing import Any, NoReturn

import typer

from coadapt_core.cli.options import _HAND_DEFAULT, leaf_default, show_default
from coadapt_core.errors import CoadaptError, PluginError, UnknownPluginError, UserError
from coadapt_core.plugins import get_registry

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
        return f"disk full writing {where}; free some space and run the command again (nothing partial was kept)"
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
    try:
        return get_registry().default(kind)
    except UnknownPluginError as exc:
        fail(str(exc))


def resolve(kind: str, name: str) -> type:
    """The plugin class for `name`, or a one-line error listing what is available."""
    try:
        return get_registry().get(kind, name)
    except UnknownPluginError as exc:
        fail(str(exc))


def config_default(name: str) -> str | None:
    """The default of a `coadapt run` option that is a config setting: the value, or the
    value per preset when the presets differ; for a learner setting, the starting policy's."""
    from coadapt_core.coadapt.config import preset_defaults

    found = preset_defaults().get(name)
    if found is None and name == "preset":  # the preset's own default: the one the others come from
        from coadapt_core.coadapt.config import CoadaptConfig
        from coadapt_core.settings import leaves

        return next(
            (leaf_default(leaf) for leaf in leaves(CoadaptConfig) if leaf.key == "preset"), None
        )
    if found is None:
        return None
    leaf, values = found
    if leaf.extra.get("plugin") or leaf.extra.get("unset"):
        return leaf_default(leaf)
    if all(v in ("", None) for v in values.values()):
        return None  # the help text says what an empty value means
    if len(set(map(repr, values.values()))) == 1:
        return show_default(next(iter(values.values())))
    return ", ".join(f"{show_default(v)} ({p})" for p, v in values.items())


def style_help(command: Any, *, config_options: bool = False) -> None:
    """One help style for every command: plain Click help (no table: option names are never
    cut at 80 columns) and every known default as `[default: X]` at the end of the text. For
    `coadapt run` (config_options) an option left unset takes the preset's value: shown per
    preset when the presets differ."""
    if hasattr(command, "rich_markup_mode"):
        command.rich_markup_mode = None
    for param in command.params:
        kind = getattr(param, "param_type_name", "")
        if kind == "argument" and getattr(param, "help", None):
            found = _HAND_DEFAULT.search(param.help)
            if found:  # arguments: the same style, the text they were given
                rest = (param.help[: found.start()] + param.help[found.end() :]).strip()
                param.help = f"{rest} [default: {(found.group(1) or found.group(2) or '').strip()}]"
            continue
        if kind != "option" or param.hidden:
            continue
        text = param.help or ""
        found = _HAND_DEFAULT.search(text)
        default = None
        if found:
            default = (found.group(1) or found.group(2) or "").strip()
            text = (text[: found.start()] + text[found.end() :]).strip()
        elif config_options and param.default is None and param.name:
            default = config_default(param.name)
        elif (
            param.default is not None
            and not (param.is_flag and param.default is False)
            and param.name != "help"
        ):
            value = param.default
            if param.is_flag and param.secondary_opts:
                default = "on" if value else "off"
            elif not param.is_flag:
                default = show_default(value)
        param.show_default = False
        if default:
            text = text.rstrip()
            text = f"{text} [default: {default}]" if text else f"[default: {default}]"
        param.help = text
    for sub in getattr(command, "commands", {}).values():
        top_run = sub.name == "run" and command.name in (None, "coadapt", "main")
        style_help(sub, config_options=top_run)
        if top_run:
            short_help(sub, RUN_COMMON_OPTIONS)


#: what `coadapt run --help` shows, in this order; `--help-all` shows every option
RUN_COMMON_OPTIONS = (
    "config",
    "resume",
    "preset",
    "objective",
    "optimizer",
    "terrain",
    "method",
    "seed",
    "robot",
    "sim",
    "mixed",
    "checkpoint",
    "out",
    "store",
    "as_json",
    "video",
    "device",
    "logger",
    "population",
    "outer_iterations",
    "optimizer_iterations",
    "train_steps",
    "eval_steps",
    "design_ranges",
)


def short_help(command: Any, common: tuple[str, ...]) -> None:
    """`--help` lists only the `common` options (in that order) and says how to see the
    rest; the command's `--help-all` option (`help_all`) lists every option, in its order."""
    original = command.format_options

    def format_options(ctx: Any, formatter: Any) -> None:
        if ctx.meta.get("coadapt_help_all"):
            return original(ctx, formatter)
        by_name = {p.name: p for p in command.get_params(ctx)}
        shown = [by_name[n] for n in common if n in by_name] + [
            by_name[n] for n in ("help_all", "help") if n in by_name
        ]
        records = [r for r in (p.get_help_record(ctx) for p in shown) if r]
        with formatter.section("Common options"):
            formatter.write_dl(records)
        hidden = sum(
            1
            for p in by_name.values()
            if getattr(p, "param_type_name", "") == "option" and not p.hidden and p not in shown
        )
        formatter.write_paragraph()
        formatter.write_text(
            f"{hidden} more options (training, task, randomization, surrogate, final check, "
            "optimizer aliases): `coadapt run --help-all`, or docs/settings.md."
        )

    command.format_options = format_options


def help_all(ctx: typer.Context, value: bool) -> None:
    """`--help-all`: the command's help with every option (see `short_help`)."""
    if not value or ctx.resilient_parsing:
        return
    ctx.meta["coadapt_help_all"] = True
    typer.echo(ctx.get_help())
    raise typer.Exit(0)


def run_app(app: typer.Typer, argv: list[str] | None = None) -> int:
    """Run the `coadapt` app (or a command of it) on `argv`; user errors become one line on
    stderr and exit code 2 (`coadapt_core.cli.main`, and `coadapt grid`'s check of its cells)."""
    command = typer.main.get_command(app)
    style_help(command)
    _INVOCATION[:] = list(sys.argv[1:] if argv is None else argv)
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
            f"error: the results store failed ({detail}); check --store / $COADAPT_STORE, or move a damaged "
            "store aside and resume the runs (`coadapt run --resume`) to record them again",
            file=sys.stderr,
        )
        return EXIT_USAGE
    return result if isinstance(result, int) else 0
