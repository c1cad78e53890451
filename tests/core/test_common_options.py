"""The options several commands share (issue 61): each declared once
(`coadapt_core.cli.common_options.CommonOptions`) and taken by every command that does that
work: a command that steps a physics engine takes `--threads`, one that draws a progress line
takes `--quiet` (`coadapt_core.cli.COMMANDS` says which do, and a command module that draws a
progress line or sets the thread budget must say so there). `coadapt run --quiet` prints no
progress line; `coadapt handoff --threads 1` gives the physics and torch one thread."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from coadapt_core.cli import COMMANDS, load_all, main
from coadapt_core.cli.common_options import CommonOptions
from coadapt_core.cli.options import DECLARED

ROOT = Path(__file__).resolve().parents[2]

#: options declared elsewhere on purpose: `coadapt run`'s seed and store are settings of its
#: config (YAML keys; an empty store means "beside --out"); grid's threads are per cell;
#: verify's seed defaults to the run's own
OWN_DECLARATION = {
    ("run", "--seed"),
    ("run", "--store"),
    ("grid", "--threads"),
    ("verify", "--seed"),
}


def _options(command, path=()) -> dict[str, set[str]]:
    """{command path: its option names} for the command and every command under it."""
    subs = getattr(command, "commands", None)
    if subs:
        out = {}
        for name, sub in subs.items():
            out.update(_options(sub, (*path, name)))
        return out
    names = {n for p in command.params for n in [*p.opts, *p.secondary_opts] if n.startswith("-")}
    return {" ".join(path): names}


OPTIONS = {
    path: names for name, c in load_all().items() for path, names in _options(c, (name,)).items()
}


@pytest.mark.parametrize("name", list(COMMANDS))
def test_a_command_that_simulates_takes_threads_and_one_with_a_progress_line_quiet(name):
    declared = COMMANDS[name]
    for path, names in OPTIONS.items():
        if path.split()[0] != name:
            continue
        if declared.simulates:
            assert "--threads" in names, f"coadapt {path} simulates but has no --threads"
        if declared.progress:
            assert "--quiet" in names, f"coadapt {path} draws a progress line but has no --quiet"


@pytest.mark.parametrize("name", list(COMMANDS))
def test_the_table_says_which_commands_simulate_and_draw_progress(name):
    """A command module that draws a progress line, or sets the thread budget (which the
    physics reads), is marked so in `COMMANDS` (so the test above covers it)."""
    source = (ROOT / "coadapt_core" / "cli" / f"{COMMANDS[name].module}.py").read_text()
    if re.search(r"ProgressLine\(|_ProgressView\(|progress=", source):
        assert COMMANDS[name].progress, name
    if "apply_threads(" in source:
        assert COMMANDS[name].simulates, name


def test_the_shared_options_are_one_declaration():
    """Every --threads, --quiet, --json, --store and --seed of every command is
    `CommonOptions`'s (help, type, default), but for the few declared elsewhere on purpose."""
    common = {f"--{f.replace('as_json', 'json')}" for f in CommonOptions.__pydantic_fields__}
    seen = 0
    for path, groups in DECLARED.items():
        for group in groups:
            for option in group:
                name = next((n for n in common if n in option.names), None)
                if name is None or (path, name) in OWN_DECLARATION:
                    continue
                source = option.leaf.extra.get("shared") or option.leaf.owner
                assert source is CommonOptions, (path, name, source)
                seen += 1
    assert seen >= 20


def test_run_quiet_prints_no_progress_line(tmp_path, monkeypatch, capsys):
    """`coadapt run --quiet` (it was refused): the same run prints its progress lines without
    it and none with it; the results are printed as usual."""
    import coadapt_core.coadapt.setup as loop_setup
    from tests.fakes.analytic import AnalyticBackend

    monkeypatch.setattr(
        loop_setup, "universal_policy_factory", lambda *a, **k: lambda seed: AnalyticBackend(seed)
    )
    monkeypatch.setenv("COADAPT_PROGRESS_EVERY", "0.001")
    base = ["run", "--preset", "smoke", "--outer-iterations", "1", "--store", "none"]
    base += ["--no-video", "--threads", "1"]
    said = {}
    for quiet in (False, True):
        out = tmp_path / f"quiet-{quiet}"
        assert main([*base, "--out", str(out), *(["--quiet"] if quiet else [])]) == 0
        captured = capsys.readouterr()
        said[quiet] = [line for line in captured.err.splitlines() if re.match(r"run +\d+%", line)]
        assert "final check costs" in " ".join(captured.out.split()), captured.out  # its table
        assert "improvement over nominal" in captured.out
    assert len(said[False]) >= 2 and said[True] == []


def test_handoff_threads_sets_the_budget_of_both_engines_and_torch(tmp_path, monkeypatch):
    """`coadapt handoff --threads 1` (it was refused): the physics of every simulator it
    evaluates on (`threads.budget()`) and torch run on one thread, as in `coadapt run`."""
    import torch

    import coadapt_core.handoff.folder as folder
    import coadapt_core.handoff.policy as policy
    from coadapt_core import threads

    run_dir = tmp_path / "runs" / "r1"
    run_dir.mkdir(parents=True)
    (run_dir / "config.yaml").write_text("robot: kuafu\n")
    seen = {}

    def make_handoff(run, out, options, progress=None):
        seen.update(budget=threads.budget(), torch=torch.get_num_threads(), sims=options.simulators)
        progress("a progress line")
        return {"out": str(out), "files": [], "seconds": 0.0}

    monkeypatch.setattr(policy, "missing_deploy_modules", lambda: [])
    monkeypatch.setattr(folder, "make_handoff", make_handoff)
    monkeypatch.setattr(threads, "_budget", None)
    before = torch.get_num_threads()
    try:
        argv = ["handoff", str(run_dir), "-o", str(tmp_path / "h"), "--threads", "1", "--quiet"]
        assert main(argv) == 0
    finally:
        torch.set_num_threads(before)
    assert seen["budget"] == 1 and seen["torch"] == 1
    assert seen["sims"] is None  # the run's simulator and every other installed one
    assert main(["handoff", str(run_dir), "--threads", "0"]) == 2
