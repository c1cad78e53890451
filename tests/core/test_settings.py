"""The settings tree of `coadapt run`: one definition gives the options, the YAML keys, the
checks and docs/settings.md; a run's config.yaml repeats its config; the learner's sections
reach the backend."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from coadapt_core.cli.options import DECLARED
from coadapt_core.cli.settings_doc import settings_markdown
from coadapt_core.coadapt.backends import learner_settings
from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.coadapt.config_loading import config_from_dict, make_config
from coadapt_core.errors import UserError
from coadapt_core.settings import leaves

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "settings.md"


def _app_command():
    from typer.main import get_command

    from coadapt_core.cli import app
    from coadapt_core.cli.help import plain_help

    command = get_command(app)
    plain_help(command)
    return command


def _command(name: str = "run"):
    """The click command of `coadapt <name>` ("robot show": a subcommand; "": `coadapt` itself)."""
    command = _app_command()
    for part in name.split():
        command = command.commands[part]
    return command


def _run_command():
    return _command("run")


def _paths(command=None, path=()):
    """Every command path of the app (`coadapt` itself as "")."""
    command = command if command is not None else _app_command()
    subs = getattr(command, "commands", None)
    if not subs or not path:
        yield " ".join(path)
    for name, sub in (subs or {}).items():
        yield from _paths(sub, (*path, name))


def documented(command: str) -> dict[str, tuple[str, str]]:
    """{first option name: (meaning, default)} of the command's rows in docs/settings.md:
    those under headings naming `coadapt <command>` (`coadapt run`: its config tables too,
    the rows before the first "# Options of" heading)."""
    sections, current = {"run": []}, "run"
    for line in DOC.read_text().splitlines():
        found = re.match(r"# Options of `coadapt ?([\w ]*)`", line)
        if found:
            current = found.group(1)
            sections.setdefault(current, [])
        elif line.startswith("| `"):
            sections[current].append(line)
    out = {}
    for row in sections.get(command, []):
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", row)[1:-1]]
        option, default, meaning = (
            (cells[1], cells[2], cells[4]) if len(cells) == 5 else (cells[0], cells[1], cells[3])
        )
        if option.startswith("`"):
            out[option.split("`")[1]] = (meaning.replace("\\|", "|"), default.replace("\\|", "|"))
    return out


def test_docs_table_is_generated_from_the_tree():
    """docs/settings.md is exactly what the tree generates (regenerate it with
    `python -m coadapt_core.cli.settings_doc > docs/settings.md`)."""
    assert DOC.read_text() == settings_markdown()


def test_run_options_table_is_the_configs_declaration():
    """`coadapt run` makes its config options from a stored table (so that its --help and a
    refusal load no config): the table is what the config declares now (regenerate:
    `python -m coadapt_core.cli.run_options > coadapt_core/cli/run_options.json`), and each
    option's help as the command shows it, installed plugins and their default included, is
    the one its declaration renders."""
    from coadapt_core.cli.help import option_help, resolved
    from coadapt_core.cli.run_options import TABLE, config_options, stored, table_text
    from coadapt_core.coadapt.config import FIELD_NAMES, preset_defaults

    assert TABLE.read_text(encoding="utf-8") == table_text(), (
        "regenerate: python -m coadapt_core.cli.run_options > coadapt_core/cli/run_options.json"
    )
    assert tuple(stored()["settings"]) == FIELD_NAMES
    presets, declared = preset_defaults(), {leaf.key: leaf for leaf in leaves(CoadaptConfig)}
    made = config_options()
    assert [o.leaf.key for o in made] == [
        k for k, leaf in declared.items() if leaf.extra.get("cli", True)
    ]
    for option in made:
        expected = resolved(option_help(declared[option.leaf.key], presets))
        assert resolved(option.option.help) == expected, option.leaf.key
    plugins = [r["key"] for r in stored()["options"] if "plugin" in r]
    assert plugins == ["robot", "sim", "optimizer", "objective"]


def test_docs_table_and_run_help_list_the_same_options_helps_and_defaults():
    run = _run_command()
    helps = {
        opt: " ".join((p.help or "").split()) for p in run.params if not p.hidden for opt in p.opts
    }
    documented_config = {
        o: v
        for o, v in documented("run").items()
        if o.lstrip("-").replace("-", "_") in {leaf.param for leaf in leaves(CoadaptConfig)}
    }
    config_options = {
        o
        for o in helps
        if o.lstrip("-").replace("-", "_") in {leaf.param for leaf in leaves(CoadaptConfig)}
    }
    assert set(documented_config) == config_options
    assert (
        len(documented_config) > 100
    )  # the run's own settings and every train / task / randomization one
    for option, (meaning, default) in documented_config.items():
        assert meaning in helps[option], option  # the declared help, word for word
        if default != "''":
            assert f"[default: {default}]" in helps[option], option


COMMANDS = list(_paths())


def test_every_command_is_declared():
    """Every command of the app, `coadapt` itself included, takes its options from settings
    classes recorded by `coadapt_core.cli.options.register`."""
    assert {
        "",
        "run",
        "train",
        "eval",
        "landscape",
        "grid",
        "report",
        "export",
        "import",
        "plugins",
        "handoff",
        "robot show",
        "robot export",
        "robot validate",
        "robot render",
    } <= set(COMMANDS)
    assert set(COMMANDS) == set(DECLARED)


@pytest.mark.parametrize("command", COMMANDS, ids=[c or "coadapt" for c in COMMANDS])
def test_each_commands_help_is_its_declarations(command):
    """Each parameter of the command (typer's --help aside) is one declared setting: the same
    names (aliases included), the declared help word for word, a shown default equal to the
    declared one; and every declared setting is a parameter. docs/settings.md lists the same
    options with the same meaning and default."""
    from coadapt_core.cli.help import HAND_DEFAULT, leaf_default

    cli = _command(command)
    params = {p.name: p for p in cli.params if p.name != "help"}
    options = {o.param: o for group in DECLARED[command] for o in group}
    config = {o.param for group in DECLARED[command] if group.root is CoadaptConfig for o in group}
    assert set(params) == set(options), set(params) ^ set(options)
    docs = documented(command)
    for name, option in options.items():
        param, leaf = params[name], option.leaf
        given = [n for names in option.names for n in names.split("/")]
        assert [*param.opts, *param.secondary_opts] == given or (
            not given and param.param_type_name == "argument"
        )
        text = " ".join((param.help or "").split())
        meaning = re.sub(r"\s*\(default:?\s+((?:[^()]|\([^()]*\))*)\)", "", leaf.help).strip()
        assert meaning.rstrip(".") in text, (command, name)
        if name in config:
            # its table and --help-all:
            # test_docs_table_and_run_help_list_the_same_options_helps_and_defaults
            continue
        default = leaf_default(leaf)
        row = docs[option.names[0].split("/")[0] if option.names else leaf.extra["argument"]]
        hidden = " (hidden from --help)" if leaf.extra.get("hidden") else ""
        assert row == (
            HAND_DEFAULT.sub("", leaf.help).strip() + hidden,
            "required" if leaf.required else default or "''",
        )
        if (
            default
            and not leaf.extra.get("hidden")
            and not (leaf.kind == "bool" and leaf.default is False)
            and not leaf.required
        ):
            assert text.endswith(f"[default: {default}]"), (command, name, text)


def test_no_command_declares_an_option_by_hand():
    """No module of the command line writes a typer option or argument itself: they are all
    made from declarations (`coadapt_core/cli/options.py`)."""
    cli = ROOT / "coadapt_core" / "cli"
    hand = [
        f"{path.name}:{n}"
        for path in sorted(cli.glob("*.py"))
        if path.name != "options.py"
        for n, line in enumerate(path.read_text().splitlines(), 1)
        if re.search(r"typer\.(Option|Argument)\(", line)
    ]
    assert hand == []


def test_a_shared_setting_is_one_declaration():
    """A setting two commands share reads the same in both: type, help, constraints, default
    (`terrain` was typed by hand in three commands)."""
    from coadapt_core.settings_leaf import Leaf

    shared = 0
    for command in COMMANDS:
        for group in DECLARED[command]:
            for option in group:
                leaf = option.leaf
                source = leaf.extra.get("shared")
                if source is None:
                    continue
                shared += 1
                mine: Leaf = {x.key: x for x in leaves(source)}[leaf.key]
                assert (leaf.help, leaf.kind, leaf.accepted(), leaf.default) == (
                    mine.help,
                    mine.kind,
                    mine.accepted(),
                    mine.default,
                )
    assert (
        shared >= 8 + 4 + 6
    )  # run's into landscape and grid; the store; robot and design in the robot commands
    run = {leaf.key: leaf for leaf in leaves(CoadaptConfig)}
    terrain_helps = {
        o.leaf.help
        for c in ("landscape", "run")
        for g in DECLARED[c]
        for o in g
        if o.leaf.key == "terrain"
    }
    assert terrain_helps == {run["terrain"].help}


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["landscape", "--grid", "1"], "error: grid must be an integer in [2, 101], got 1"),
        (
            ["landscape", "--terrain", "moon"],
            "error: terrain 'moon' is not one of flat, slope, random",
        ),
        (["landscape", "--cost-cap", "1"], "error: cost_cap must be a finite number > 1, got 1"),
        (["landscape", "--agents", "0"], "error: agents must be an integer >= 1, got 0"),
        (["grid", "--timeout", "nan"], "error: timeout must be a finite number"),
        # every error starts `error:`, a usage error with its command at the end (issue 43)
        (["robot", "render", "kuafu", "--width", "abc"], "error: Invalid value for '--width'"),
        (["export"], "error: Missing option '-o' / '--out'. (coadapt export)"),
        (["handoff"], "error: Missing argument 'run'. (coadapt handoff)"),
        (
            ["report", "--transfer-agents", "0"],
            "error: --transfer-agents, --transfer-steps and --common-blocks must be >= 1",
        ),
    ],
)
def test_a_bad_value_of_another_command_is_one_line_naming_the_setting(argv, message, capsys):
    from coadapt_core.cli import main

    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(message) and "\n" not in err, err


def test_every_setting_is_an_option_or_a_yaml_key():
    run = _run_command()
    options = {opt for p in run.params for opt in p.opts}
    for leaf in leaves(CoadaptConfig):
        if leaf.extra.get("cli", True):
            assert leaf.option in options, leaf.key
    # train, task and randomization settings all reach the command line
    for section in ("train", "task", "randomization"):
        assert sum(o.startswith(f"--{section}-") for o in options) >= 10, section


def test_a_runs_config_yaml_round_trips(tmp_path, monkeypatch):
    """A run folder's config.yaml, given back to --config, is the identical config."""
    import coadapt_core.coadapt.setup as loop_setup
    from coadapt_core.cli import main
    from tests.fakes.analytic import AnalyticBackend

    monkeypatch.setattr(
        loop_setup, "universal_policy_factory", lambda *a, **k: lambda seed: AnalyticBackend(seed)
    )
    args = [
        "run",
        "--preset",
        "smoke",
        "--population",
        "6",
        "--narrow-margin",
        "0.3",
        "--train-epochs",
        "3",
        "--task-commands-yaw-range",
        "-0.5:0.5",
        "--task-rewards-weights",
        "raibert=-1",
        "--randomization-preset",
        "engine",
        "--randomization-friction",
        "0.6:1.1",
        "--store",
        "none",
        "--out",
        str(tmp_path),
        "--no-video",
        "--json",
    ]
    assert main(args) == 0
    (folder,) = [p for p in tmp_path.iterdir() if (p / "config.yaml").is_file()]
    recorded = yaml.safe_load((folder / "config.yaml").read_text())
    assert recorded["train"]["epochs"] == 3 and recorded["train"]["learning_rate"] is None
    assert recorded["task"]["commands"]["yaw_range"] == [-0.5, 0.5]
    assert recorded["randomization"] == {
        **{k: None for k in recorded["randomization"]},
        "preset": "engine",
        "friction": [0.6, 1.1],
    }
    again = make_config(None, folder / "config.yaml", {})
    assert again == config_from_dict(recorded)
    records = (
        "run_id",
        "run_dir",
        "design_space",
        "policy",
        "threads",
    )  # beside the config, not read back
    assert again.to_dict() == {k: v for k, v in recorded.items() if k not in records}
    from coadapt_core.threads import usable_cpus

    assert recorded["threads"] == usable_cpus()  # no --threads: the CPUs the process may use
    assert (again.population, again.narrow_margin, again.preset) == (6, 0.3, "smoke")


def test_sections_apply_over_the_starting_policys_settings(tmp_path):
    import torch

    from coadapt_core.learning.config import TrainConfig
    from coadapt_core.learning.trainer import CHECKPOINT_FORMAT
    from coadapt_core.physics.randomization import RandomizationConfig
    from coadapt_core.task.config import TaskConfig

    # a checkpoint's recorded settings are the base the run's keys apply over
    saved_task = TaskConfig.from_dict({"commands": {"yaw_range": [0.0, 0.0]}, "history": 5})
    path = tmp_path / "policy.pt"
    torch.save(
        {
            "format": CHECKPOINT_FORMAT,
            "train_config": TrainConfig(epochs=7, extra={"randomization": "engine"}).to_dict(),
            "task_config": saved_task.to_dict(),
        },
        path,
    )
    config = make_config(
        "smoke",
        None,
        {
            "train.learning_rate": 3e-4,
            "task.rewards.weights": "raibert=-1",
            "randomization.delay": "0:0.01",
        },
    )
    got = learner_settings(config, str(path))
    assert got["train_config"].epochs == 7 and got["train_config"].learning_rate == 3e-4
    assert got["task_config"].commands.yaw_range == (0.0, 0.0)  # kept from the checkpoint
    weights = got["task_config"].rewards.weights
    assert (
        weights["raibert"] == -1.0 and weights["termination"] == -200.0
    )  # other terms keep theirs
    engine = RandomizationConfig.engine_robust()  # the checkpoint's preset, one range replaced
    assert (
        got["randomization"].delay == (0.0, 0.01)
        and got["randomization"].joint_damping == engine.joint_damping
    )
    # nothing set: the backend takes everything from the checkpoint, as before
    assert learner_settings(make_config("smoke"), str(path)) == {}


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"population": 0}, "population must be an integer >= 1, got 0"),
        ({"narrow_margin": -1}, "narrow_margin must be a finite number >= 0, got -1"),
        ({"narrow_min_width": 1.5}, "narrow_min_width must be a finite number in (0, 1], got 1.5"),
        ({"seed": True}, "seed must be an integer >= 0"),
        ({"mixed": "maybe"}, "mixed must be true or false, got 'maybe'"),
        ({"logger": "csv"}, "logger 'csv' is not one of tensorboard, wandb, none"),
        ({"train.epochs": 0}, "train.epochs must be an integer >= 1, got 0"),
        ({"train.gamma": 1.5}, "train.gamma must be a finite number in (0, 1), got 1.5"),
        (
            {"task.commands.vx_range": "1:-1"},
            "task.commands.vx_range must be a range low:high, got '1:-1'",
        ),
        ({"task.noise.kind": "pink"}, "task.noise.kind 'pink' is not one of uniform, gaussian"),
        ({"task.rewards.weights": "speed=1"}, "task.rewards.weights: unknown term(s) ['speed']"),
        (
            {"randomization.friction": "0:1"},
            "randomization.friction must be a range low:high of positive numbers",
        ),
        (
            {"randomization.preset": "wild"},
            "randomization.preset 'wild' is not one of table2, engine, off",
        ),
        ({"train.nope": 1}, "unknown key 'train.nope'"),
    ],
)
def test_bad_values_name_the_key_and_what_it_accepts(overrides, message):
    with pytest.raises(UserError) as info:
        make_config("smoke", None, overrides)
    text = str(info.value)
    assert message in text and "\n" not in text
    assert info.value.field == next(iter(overrides)) or "unknown" in text


def test_yaml_sections_merge_with_options(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("train: {epochs: 2, gamma: 0.98}\ntask:\n  commands: {yaw_range: [0, 0]}\n")
    config = make_config("smoke", path, {"train.epochs": 4})
    assert (config.train.epochs, config.train.gamma) == (4, 0.98)  # the option wins key by key
    assert config.task.commands.yaw_range == (0.0, 0.0)
    path.write_text("train: 3\n")
    with pytest.raises(UserError, match="train must be a mapping"):
        make_config("smoke", path, {})


def test_train_takes_the_same_sections_and_a_resume_keeps_them(tmp_path, capsys):
    """`coadapt train` reads the trainer, task and randomization settings from the same
    declarations as the run; what it was given is recorded in the checkpoint, so --resume
    trains on the same task and draws the same randomization ranges."""
    from coadapt_core.cli import main
    from coadapt_core.learning.checkpoints import read_checkpoint
    from coadapt_core.physics.randomization import RandomizationConfig

    out = tmp_path / "run"
    assert (
        main(
            [
                "train",
                "--steps",
                "64",
                "--num-designs",
                "2",
                "--agents",
                "4",
                "--steps-per-env",
                "8",
                "--epochs",
                "1",
                "--minibatches",
                "2",
                "--gamma",
                "0.98",
                "--yaw-range=0:0",
                "--task-rewards-weights",
                "raibert=-1",
                "--randomization",
                "engine",
                "--randomization-delay",
                "0:0.01",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    state = read_checkpoint(out / "model_final.pt")
    assert state["train_config"]["gamma"] == 0.98
    assert state["train_config"]["extra"] == {
        "randomization": "engine",
        "randomization_ranges": {"delay": [0.0, 0.01]},
    }
    assert tuple(state["task_config"]["commands"]["yaw_range"]) == (0.0, 0.0)
    assert state["task_config"]["rewards"]["weights"]["raibert"] == -1.0
    recorded = RandomizationConfig.recorded(state["train_config"]["extra"])
    assert (
        recorded.delay == (0.0, 0.01)
        and recorded.joint_damping == RandomizationConfig.engine_robust().joint_damping
    )
    capsys.readouterr()
    # a bad value is one line naming the setting, exit 2
    assert main(["train", "--steps", "64", "--epochs", "0", "--out", str(tmp_path / "bad")]) == 2
    assert capsys.readouterr().err.strip() == "error: epochs must be an integer >= 1, got 0"


def test_grid_run_args_of_any_setting_count_in_the_config_hash():
    """A grid's --run-arg may be any setting of the tree (a section's too): the cell's config
    hash is then known and equals that of a run made by hand with the same setting."""
    from coadapt_core.experiments.cell import Cell
    from coadapt_core.experiments.cell_hash import cell_config_hash, config_hash

    cell = Cell("ours", "torque", "flat", 0, "smoke", "mujoco")
    base = {"method": "ours", "objective": "torque", "terrain": "flat", "seed": 0, "sim": "mujoco"}
    with_epochs = cell_config_hash(cell, ["--train-epochs", "3"])
    assert with_epochs is not None and with_epochs != cell_config_hash(cell)
    assert with_epochs == config_hash(
        make_config("smoke", None, {**base, "train.epochs": 3}).to_dict()
    )
    no_fit = cell_config_hash(cell, ["--no-fit-surrogate", "--task-commands-yaw-range=0:0"])
    expected = make_config(
        "smoke", None, {**base, "fit_surrogate": False, "task.commands.yaw_range": "0:0"}
    )
    assert no_fit == config_hash(expected.to_dict())
    assert cell_config_hash(cell, ["--no-such-option", "1"]) is None
