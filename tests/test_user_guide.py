"""Every command docs/user-guide.md shows runs, in smoke form: the same command line with
options appended that make it small (the last value of an option wins), from a scratch
folder. Bad documentation (a removed option, a wrong exit code) fails here."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from coadapt_core.cli import main

GUIDE = Path(__file__).resolve().parents[1] / "docs" / "user-guide.md"
TINY_RUN = [
    "--preset",
    "smoke",
    "--population",
    "3",
    "--agents-per-design",
    "2",
    "--eval-steps",
    "10",
    "--train-steps",
    "64",
    "--retrain-steps",
    "32",
    "--outer-iterations",
    "1",
    "--optimizer-iterations",
    "2",
    "--bo-designs",
    "2",
    "--specialized-train-steps",
    "32",
    "--no-video",
]
#: options appended per command (click: the last occurrence of an option wins)
SMOKE = {
    "run": TINY_RUN,
    "train": [
        "--steps",
        "64",
        "--num-designs",
        "2",
        "--agents",
        "2",
        "--steps-per-env",
        "8",
        "--epochs",
        "1",
        "--minibatches",
        "1",
        "--quiet",
    ],
    "eval": ["--agents", "2", "--seconds", "0.2"],
    "grid": ["--workers", "2", *(f"--run-arg={a}" for a in TINY_RUN)],
    "landscape": ["--grid", "2", "--agents", "1", "--steps", "5"],
    "report": ["--no-sim-to-sim"],  # the PyBullet transfer of every run is the slow part
}


def documented_commands() -> list[tuple[list[str], int]]:
    """(argv after `coadapt`, expected exit code) of every command in the guide's bash blocks;
    placeholders (`...`) and cluster-only lines are left out."""
    text = GUIDE.read_text()
    out = []
    for block in re.findall(r"```bash\n(.*?)```", text, re.S):
        for line in block.splitlines():
            command = line.partition("#")[0]
            command = command.strip()
            if not command.startswith("coadapt ") or "..." in command:
                continue
            out.append((shlex.split(command)[1:], 0))
    return out


COMMANDS = documented_commands()


def test_the_guide_documents_every_command():
    firsts = {argv[0] for argv, _ in COMMANDS}
    assert {
        "plugins",
        "robot",
        "run",
        "train",
        "eval",
        "grid",
        "landscape",
        "report",
        "export",
    } <= firsts


@pytest.mark.slow
def test_every_documented_command_runs_in_smoke_form(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("COADAPT_STORE", raising=False)
    failures = []
    for argv, expected in COMMANDS:
        args = [*argv, *SMOKE.get(argv[0], [])]
        code = main(args)
        captured = capsys.readouterr()
        if code != expected:
            failures.append(
                f"coadapt {shlex.join(args)} -> exit {code}: "
                f"{captured.err.strip().splitlines()[-1:]}"
            )
    assert not failures, "\n".join(failures)
    assert (tmp_path / "report" / "report.html").is_file() and (
        tmp_path / "export" / "runs.csv"
    ).is_file()
