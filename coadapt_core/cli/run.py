"""`coadapt run`: the co-adaptation loop (Algorithm 4) on one robot, simulator and objective.

Every option is a field of `coadapt_core.coadapt.config.CoadaptConfig` (and a YAML key of
`--config`); an option given on the command line wins over the YAML file, which wins over
the preset.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import typer

from coadapt_core.cli.common import ctrl_c_once, fail, interrupted, resolve
from coadapt_core.cli.common_options import CommonOptions
from coadapt_core.cli.help import help_all
from coadapt_core.cli.options import LateGroup, OptionGroup, filled, options_of
from coadapt_core.cli.options import register as register_command
from coadapt_core.cli.progress import ProgressLine, fmt_duration
from coadapt_core.cli.run_summary import report
from coadapt_core.errors import UserError
from coadapt_core.settings import Float, Int, setting, settings, shared
from coadapt_core.tracking import check_logger


@settings
class RunCommand:
    """`coadapt run`'s own options, which are not config settings (no YAML key): where the
    config and the run come from, and what is printed and rendered at the end."""

    config: Path | None = setting(
        None,
        "YAML file of config keys (CLI options win over it); a run folder's config.yaml "
        "repeats that run's config.",
    )
    resume: str | None = setting(
        None,
        "Resume the run with this id (a folder under --out) or this run folder; its recorded "
        "config holds, but --store names the store this session writes to.",
    )
    as_json: Any = shared(CommonOptions)
    quiet: Any = shared(CommonOptions)
    verify: bool = setting(
        False,
        "When the run has finished, `coadapt verify` it: specialists fine-tuned at the best and "
        "the nominal design, the final check repeated with each on its own (docs/cli/verify.md).",
        names=("--verify",),
    )
    verify_budget: Int | None = setting(
        None,
        "--verify: interactions per specialist (default by preset: smoke 2,000, quick "
        "1,000,000, paper 10,000,000).",
    )
    video: bool = setting(
        True,
        "End by rendering the best and the nominal design walking side by side: <run "
        "folder>/best_vs_nominal.gif (and .mp4 with ffmpeg).",
    )
    optimizer_option: list[str] | None = setting(
        None,
        "KEY=VALUE: an option the optimizer plugin declares (repeatable; "
        "`coadapt plugins --json` lists them); wins over the YAML file's optimizer_options.",
        names=("--optimizer-option",),
    )
    objective_option: list[str] | None = setting(
        None,
        "KEY=VALUE: an option the objective plugin declares (repeatable); wins over the YAML "
        "file's objective_options.",
        names=("--objective-option",),
    )
    threads: Any = shared(CommonOptions)
    help_all: bool = setting(
        False,
        "Show every option (training, task, randomization, ...) and exit.",
        names=("--help-all",),
        callback=help_all,
    )
    check: bool = setting(
        False,
        "Check the options (config, plugins, starting policy, store, --out) and exit without "
        "running.",
        names=("--check",),
        hidden=True,
    )


class _ProgressView:
    """One progress line: phase, outer/inner iteration, best real cost, interactions,
    elapsed and ETA (a bar on a terminal, a plain line every 10 s otherwise, also during a
    long phase). The ETA is the loop's (`CoadaptationLoop.eta_seconds`: measured seconds per
    training interaction and per round), "?" until a training phase and a real round ran."""

    def __init__(self, enabled: bool):
        self.line = ProgressLine("run", 1.0, enabled=enabled, own_eta=True)
        self.announce: str | None = None  # "run <id>: <folder>", said once the run is under way

    def __enter__(self) -> _ProgressView:
        return self

    def __call__(self, event: dict[str, Any]) -> None:
        if self.announce:  # not before: a bad option found while starting stays one line
            print(self.announce, file=sys.stderr, flush=True)
            self.announce = None
        best = event["best_cost"] if event["best_cost"] is not None else event.get("best_any")
        outer = f"{min(event['outer'] + 1, event['outer_total'])}/{event['outer_total']}"
        phase, done = event["phase"], event.get("phase_done") or 0
        if event.get("phase_total"):  # inside a training phase (coadapt_core.phase_progress)
            phase += (
                f" {100 * done / event['phase_total']:.0f}% of {event['phase_total']:,}, phase ETA "
                f"{fmt_duration(event.get('phase_eta'))}"
            )
        self.line.update(
            event["fraction"],
            # most telling first: at 80 columns the end of the line is cut; the cost is the
            # optimizer's in-run estimate (a round's scenarios), not the final check's
            f"in-run best {'-' if best is None else f'{best:.4g}'}  outer {outer} round "
            f"{event['inner']}/{event['inner_total']}  {phase}  "
            f"{event['interactions'] + done:,} interactions",
            eta=event.get("eta"),
        )

    def close(self) -> None:
        self.line.close()

    def __exit__(self, *exc: Any) -> None:
        self.line.close()


def _check_run_config(cfg: Any) -> None:
    """What `coadapt run` would only find out later: the store URL and its driver, the BO
    study's storage URL, the starting policy, and that --out is (or can be made) a folder."""
    import os

    from coadapt_core.results.storage import (
        ENV_STORE,
        NO_STORE,
        check_database_url,
        resolve_store_url,
    )

    store = cfg.store or os.environ.get(ENV_STORE) or ""
    if store and store.strip().lower() not in NO_STORE:
        check_database_url(resolve_store_url(store), field="store")
    from coadapt_core.coadapt.config_aliases import option_aliases

    # an optimizer option `storage` is a database URL (a study kept there); named as its alias
    options = getattr(cfg, "optimizer_options", None) or {}
    storage = options.get("storage") if isinstance(options, dict) else None
    if storage:
        field = next(
            (
                a.key
                for a in option_aliases().values()
                if (a.field, a.option.name) == ("optimizer_options", "storage")
            ),
            "optimizer_options.storage",
        )
        check_database_url(str(storage), field=field)
    from coadapt_core.coadapt.starting_policy import check_starting_policy

    # a robot without a policy: one line (a grid's cell before the grid starts)
    check_starting_policy(cfg)
    Path(cfg.out).mkdir(parents=True, exist_ok=True)  # an OSError here is one line (cli.main)


def _render_video(run_dir: Path, summary: dict[str, Any], *, progress: bool = True) -> None:
    """Best vs nominal, walking, from the run's final policy; smoke runs get a short one."""
    import yaml

    from coadapt_core.viz.video import render_run_video

    try:
        config = yaml.safe_load((run_dir / "config.yaml").read_text()) or {}
    except (OSError, yaml.YAMLError):
        config = {}
    smoke = summary.get("preset") == "smoke"
    with ProgressLine("video", 1.0, enabled=progress) as line:
        render_run_video(
            run_dir,
            summary,
            config,
            seconds=1.0 if smoke else 4.0,
            width=240 if smoke else 320,
            height=240 if smoke else 320,
            progress=lambda done, detail: line.update(done, detail),
        )


def resume_command(run_id: str, run_dir: Path, *, video: bool = True, as_json: bool = False) -> str:
    """The exact `coadapt run --resume` command line that continues this run from here (the
    run folder's parent as --out unless it is the default ./runs)."""
    import os
    import shlex

    parts = ["coadapt", "run", "--resume", run_id]
    parent = Path(run_dir).absolute().parent
    if parent != Path("runs").absolute():
        relative = os.path.relpath(parent)
        parts += ["--out", relative if not relative.startswith("..") else str(parent)]
    if not video:
        parts.append("--no-video")
    if as_json:
        parts.append("--json")
    return shlex.join(parts)


def alias_settings_class() -> type:
    """The keys of earlier versions that the installed plugins declare for their options
    (`PluginOption.alias`), as a settings class: `--<alias>` sets that plugin option."""
    import dataclasses

    from coadapt_core.cli.run_options import stored
    from coadapt_core.coadapt.config_aliases import option_aliases

    table = stored()  # the config's names, without the config (`coadapt run --help` reads them)
    taken = set(table["params"]) | set(RunCommand.__pydantic_fields__)
    specs = []
    for key, alias in option_aliases(table["settings"]).items():
        if key in taken:
            continue
        spec, kind = alias.option, alias.field.removesuffix("_options")
        text = (
            f"Alias of --{kind}-option {spec.name}=... ({', '.join(alias.plugins)}: {spec.help})."
        )
        specs.append(
            (key, {"float": Float, "int": Int}.get(spec.type, str) | None, setting(None, text))
        )
    made = dataclasses.make_dataclass("PluginOptionAliases", specs)
    made.__module__ = __name__
    made = settings(made)
    made.__doc__ = (
        "Built by `alias_settings_class()` from the installed plugins' declarations "
        "(`PluginOption.alias`): older top-level names of plugin options; `--<alias> X` is "
        "`--optimizer-option NAME=X` (or "
        "`--objective-option`)."
    )
    return made


def config_options() -> OptionGroup:
    """The options of every config setting on the command line (their defaults: the preset's),
    from the table stored from the config's declaration (`coadapt_core.cli.run_options`): the
    command is made, and refuses a bad option, without loading the config's classes."""
    from coadapt_core.cli.run_options import config_options as stored_options

    return stored_options()


def _resume_folder(resume: str, out: str | None) -> Path:
    """The folder of the run --resume names: a run id is looked up inside --out first (the
    grid resumes by id); otherwise --resume is the run folder itself."""
    from coadapt_core.validation import is_run_id, run_folder

    run_dir = (
        run_folder(out or "runs", resume, field="resume") if is_run_id(resume) else Path(resume)
    )
    if not run_dir.is_dir() and is_run_id(resume) and Path(resume).is_dir():
        run_dir = Path(resume)
    if not run_dir.is_dir():
        fail(f"--resume: no run '{resume}' under {out or 'runs'}/ (and no such folder)")
    return run_dir


def _new_config(values: dict[str, Any], overrides: dict[str, Any]) -> Any:
    """The config of a new run (preset, YAML file, options), its plugins resolved; None
    after `--check` (`coadapt grid` checks every cell's arguments before it starts any)."""
    from coadapt_core.coadapt.config_loading import make_config
    from coadapt_core.options import parse_assignments

    if values["optimizer_option"]:
        overrides["optimizer_options"] = parse_assignments(
            values["optimizer_option"], "optimizer_options"
        )
    if values["objective_option"]:
        overrides["objective_options"] = parse_assignments(
            values["objective_option"], "objective_options"
        )
    cfg = make_config(values["preset"], values["config"], overrides)
    if cfg.checkpoint.strip() and Path(cfg.checkpoint.strip()).is_dir():
        from coadapt_core.io import checkpoint_path

        # a `coadapt train --out` folder: its newest checkpoint, recorded as that file
        cfg.checkpoint = str(checkpoint_path(cfg.checkpoint.strip(), field="--checkpoint"))
    resolve("optimizer", cfg.optimizer)
    check_logger(cfg.logger)  # wandb asked for but not installed: one line, exit 2
    resolve("simulator", cfg.sim)
    resolve("robot", cfg.robot)
    for name in cfg.objectives:
        resolve("objective", name)
    if values["check"]:
        _check_run_config(cfg)
        return None
    if cfg.checkpoint.strip().lower() == "none":
        from coadapt_core.coadapt.reliability import WALKING_GATE

        print(
            f"note: no starting policy (--checkpoint none): robot '{cfg.robot}' is trained from "
            f"scratch in this run; its result is marked unreliable unless the real rounds pass "
            f"the walking gate ({WALKING_GATE.describe()})",
            file=sys.stderr,
        )
    return cfg


def _run_loop(cfg: Any, kwargs: dict[str, Any], values: dict[str, Any]) -> Any:
    """Run (or resume) the loop with the progress line and, at its end, the video; Ctrl-C
    says where the run stopped and the exact command that continues it."""
    from coadapt_core.coadapt.run import run_coadaptation

    resume, out, video, as_json = (
        values["resume"],
        values["out"],
        values["video"],
        values["as_json"],
    )
    quiet = as_json or values["quiet"]  # no progress line (the JSON's last line stays alone)
    started: dict[str, Any] = {}

    def on_start(run_id: str, run_dir: Path) -> None:
        started.update(run_id=run_id, run_dir=run_dir)
        view.announce = f"run {run_id}: {run_dir}"

    def finishing(result: Any) -> None:
        view.close()
        # a finished run resumed again keeps the video it has
        if video and not (resume and (result.run_dir / "best_vs_nominal.gif").is_file()):
            _render_video(result.run_dir, result.summary, progress=not quiet)

    with ctrl_c_once(), _ProgressView(enabled=not quiet) as view:
        try:
            return run_coadaptation(
                cfg, progress=view, on_start=on_start, finishing=finishing, **kwargs
            )
        except KeyboardInterrupt:
            view.close()
            if not started and resume:  # stopped while loading it: it is where it was
                import shlex

                interrupted(
                    f"run {resume} was not continued",
                    shlex.join(
                        [
                            "coadapt",
                            "run",
                            "--resume",
                            resume,
                            *(["--out", out] if out and out != "runs" else []),
                        ]
                    ),
                )
            if not started:
                interrupted("the run had not started; nothing to resume", None)
            interrupted(
                f"run {started['run_id']} stopped; its folder {started['run_dir']} keeps the "
                "last state",
                resume_command(started["run_id"], started["run_dir"], video=video, as_json=as_json),
            )


def _check_plugin_names(values: dict[str, Any]) -> None:
    """Plugin names given on the command line, checked against the registry before torch loads
    (the registry lists and loads the plugins without it): a typo is one line, exit 2."""
    for kind, key in (("robot", "robot"), ("simulator", "sim"), ("optimizer", "optimizer")):
        if values.get(key):
            resolve(kind, values[key])
    given = values.get("objective") or []
    for item in [given] if isinstance(given, str) else given:
        for name in str(item).split(","):
            if name.strip():
                resolve("objective", name.strip())


def register(app: typer.Typer) -> None:
    settings, own = config_options(), options_of(RunCommand)
    # the installed plugins' aliases: made only for a `coadapt run` whose command line may
    # hold one (an option that is no other of its options) or asks for its help
    known = {n for group in (settings, own) for o in group for x in o.names for n in x.split("/")}
    aliases = LateGroup(
        lambda: options_of(alias_settings_class(), per_preset=True, presets={}),
        lambda argv: any(
            w.split("=")[0] not in known or w in ("--help", "--help-all")
            for w in argv
            if w.startswith("-")
        ),
    )

    def run_command(**values: Any) -> None:
        """Co-adapt design and policy: universal policy + pseudo-critics, optimizer with hybrid
        real/surrogate fitness, range narrowing (paper Algorithm 4)."""
        values = filled(values, own)
        from coadapt_core.coadapt.presets import check_preset

        try:  # a typo is refused before torch and the plugins load
            check_preset(values["preset"])
        except UserError as exc:
            fail(str(exc))
        if values["verify_budget"] is not None and values["verify_budget"] <= 0:
            fail(
                "--verify-budget must be a positive number of interactions, got "
                f"{values['verify_budget']}"
            )
        _check_plugin_names(values)
        from coadapt_core.threads import apply_threads

        apply_threads(values["threads"])  # physics and torch alike; recorded in config.yaml
        overrides = {option.leaf.key: values[option.param] for option in settings}
        for option in aliases:  # keys of earlier versions, declared by the plugins
            overrides[option.param] = values.get(option.param)  # none on this command line
        try:
            if values["resume"]:
                cfg, kwargs = None, {"resume": _resume_folder(values["resume"], values["out"])}
                if overrides.get("store"):  # rows go there this time, not to the recorded store
                    from coadapt_core.results.recorders import make_recorder

                    kwargs["recorder"] = make_recorder(kwargs["resume"], overrides["store"])
            else:
                cfg, kwargs = _new_config(values, overrides), {}
                if cfg is None:  # --check
                    return
            result = _run_loop(cfg, kwargs, values)
            if values["verify"]:
                from coadapt_core.cli.verify import run_stage

                run_stage(result, values)
        except UserError as exc:
            fail(str(exc))
        report(result, values["as_json"])

    register_command(app, "run", run_command, settings, own, aliases)
