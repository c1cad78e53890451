"""Every bad input the issue lists: exit code 2, exactly one line of error, no traceback.

The list is the one a new user produced (issue 12): bad store URLs, a store that is not a
database, a PostgreSQL URL without its driver, --out on a read-only folder or naming a file,
unknown devices, a binary --config, bad train and grid options, grid cells that would fail,
a checkpoint made for another robot, an unknown transfer simulator, repeated objectives and
YAML booleans that are not booleans. `grid` must refuse before it starts any cell.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import pytest
import torch

from coadapt_core.cli import main

RO = "/sys/coadapt-readonly"  # creating anything there fails (EPERM / EROFS), even as root
SMOKE = [
    "--preset",
    "smoke",
    "--population",
    "2",
    "--outer-iterations",
    "1",
    "--optimizer-iterations",
    "1",
    "--agents-per-design",
    "1",
    "--eval-steps",
    "2",
    "--train-steps",
    "10",
]
GRID = [
    "grid",
    "--methods",
    "ours",
    "--objectives",
    "torque",
    "--terrains",
    "flat",
    "--seeds",
    "0",
    "--preset",
    "smoke",
]
LAND = ["landscape", "--grid", "2", "--agents", "1", "--steps", "2"]


def grid(T: str, *extra: str) -> list[str]:
    return [*GRID, "--store", f"{T}/g.db", "--out", f"{T}/g", *extra]


CASES: list[tuple[str, list[str], dict[str, str]]] = [
    ("run --store bad://", ["run", *SMOKE, "--store", "bad://x", "--out", "{T}/o"], {}),
    ("run $COADAPT_STORE=bad://", ["run", *SMOKE, "--out", "{T}/o"], {"COADAPT_STORE": "bad://x"}),
    ("report --store bad://", ["report", "--store", "bad://x", "--out", "{T}/rep"], {}),
    ("export --store bad://", ["export", "--store", "bad://x", "--out", "{T}/exp"], {}),
    ("grid --store bad://", [*GRID, "--store", "bad://x", "--out", "{T}/g"], {}),
    ("landscape --store bad://", [*LAND, "--store", "bad://x"], {}),
    (
        "run --bo-storage bad://",
        [
            "run",
            *SMOKE,
            "--method",
            "bo-specialized",
            "--bo-storage",
            "bad://x",
            "--store",
            "none",
            "--out",
            "{T}/o",
        ],
        {},
    ),
    (
        "report --store not-a-database",
        ["report", "--store", "{T}/notdb.db", "--out", "{T}/rep"],
        {},
    ),
    (
        "export --store not-a-database",
        ["export", "--store", "{T}/notdb.db", "--out", "{T}/exp"],
        {},
    ),
    ("grid --store not-a-database", [*GRID, "--store", "{T}/notdb.db", "--out", "{T}/g"], {}),
    (
        "report --store postgresql without driver",
        ["report", "--store", "postgresql://u@127.0.0.1:1/db", "--out", "{T}/rep"],
        {},
    ),
    ("run --out names a file", ["run", *SMOKE, "--store", "none", "--out", "{T}/afile"], {}),
    ("run --out read-only", ["run", *SMOKE, "--store", "none", "--out", RO], {}),
    ("train --out names a file", ["train", "--steps", "8", "--out", "{T}/afile"], {}),
    ("train --out read-only", ["train", "--steps", "8", "--out", RO], {}),
    ("grid --out names a file", [*grid("{T}")[:-2], "--out", "{T}/afile"], {}),
    ("grid --out read-only", [*grid("{T}")[:-2], "--out", RO], {}),
    ("report --out names a file", ["report", "--store", "{T}/r.db", "--out", "{T}/afile"], {}),
    ("report --out read-only", ["report", "--store", "{T}/r.db", "--out", RO], {}),
    ("export --out names a file", ["export", "--store", "{T}/r.db", "--out", "{T}/afile"], {}),
    ("export --out read-only", ["export", "--store", "{T}/r.db", "--out", RO], {}),
    (
        "run --device tpu",
        ["run", *SMOKE, "--store", "none", "--device", "tpu", "--out", "{T}/o"],
        {},
    ),
    ("landscape --device tpu", [*LAND, "--device", "tpu", "--store", "{T}/l.db"], {}),
    (
        "run --config binary",
        ["run", "--config", "{T}/binary.yaml", "--store", "none", "--out", "{T}/o"],
        {},
    ),
    ("train --threads 0", ["train", "--steps", "8", "--threads", "0", "--out", "{T}/t"], {}),
    ("run --threads 0", ["run", *SMOKE, "--threads", "0", "--store", "none", "--out", "{T}/o"], {}),
    ("grid --threads 0", grid("{T}", "--threads", "0"), {}),
    (
        "train --objectives torque,torque",
        ["train", "--steps", "8", "--objectives", "torque,torque", "--out", "{T}/t"],
        {},
    ),
    ("grid --timeout nan", grid("{T}", "--timeout", "nan"), {}),
    ("grid --timeout -1", grid("{T}", "--timeout", "-1"), {}),
    (
        "grid unknown objective",
        [*GRID[:4], "nope", *GRID[5:], "--store", "{T}/g.db", "--out", "{T}/g"],
        {},
    ),
    (
        "grid unknown terrain",
        [*GRID[:6], "moon", *GRID[7:], "--store", "{T}/g.db", "--out", "{T}/g"],
        {},
    ),
    ("grid unknown preset", [*GRID[:-1], "nope", "--store", "{T}/g.db", "--out", "{T}/g"], {}),
    ("grid unknown simulator", grid("{T}", "--sim", "nope"), {}),
    ("grid unknown optimizer", grid("{T}", "--optimizer", "nope"), {}),
    ("grid --seeds -1", [*GRID[:8], "-1", *GRID[9:], "--store", "{T}/g.db", "--out", "{T}/g"], {}),
    ("grid bad --run-arg value", grid("{T}", "--run-arg=--population=-3"), {}),
    ("grid unknown --run-arg", grid("{T}", "--run-arg=--no-such-option"), {}),
    ("grid --executor nope", grid("{T}", "--executor", "nope"), {}),
    ("grid --workers 0", grid("{T}", "--workers", "0"), {}),
    ("grid --workers -1", grid("{T}", "--workers", "-1"), {}),
    (
        "grid ray address unreachable",
        grid("{T}", "--executor", "ray", "--address", "127.0.0.1:1"),
        {},
    ),
    (
        "grid ray address unknown host",
        grid("{T}", "--executor", "ray", "--address", "not-a-host.invalid:1"),
        {},
    ),
    ("robot render -o read-only", ["robot", "render", "kuafu", "-o", "/sys/coadapt-x.png"], {}),
    (
        "run --checkpoint of another robot",
        ["run", *SMOKE, "--checkpoint", "{T}/other-robot.pt", "--store", "none", "--out", "{T}/o"],
        {},
    ),
    (
        "landscape --checkpoint of another robot",
        [*LAND, "--checkpoint", "{T}/other-robot.pt", "--store", "{T}/l.db"],
        {},
    ),
    (  # Kuafu's policy of the mixed space (4 design values) on the 2-value landscape
        "landscape --checkpoint of the mixed space",
        [*LAND, "--checkpoint", "{T}/mixed.pt", "--store", "{T}/l.db"],
        {},
    ),
    (
        "report --transfer-sim nope",
        ["report", "--store", "{T}/r.db", "--out", "{T}/rep", "--transfer-sim", "nope"],
        {},
    ),
    (
        "yaml mixed: maybe",
        ["run", "--config", "{T}/maybe.yaml", "--store", "none", "--out", "{T}/o"],
        {},
    ),
    ("import a file that is no export", ["import", "{T}/afile", "--store", "{T}/i.db"], {}),
    ("import binary export files", ["import", "{T}/binexp/runs.csv", "--store", "{T}/i.db"], {}),
    ("import --store not-a-database", ["import", "{T}/binexp", "--store", "{T}/notdb.db"], {}),
]


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    T = tmp_path_factory.mktemp("bad")
    (T / "afile").write_text("a file, not a folder\n")
    (T / "notdb.db").write_text("this is not an SQLite database\n" * 20)
    (T / "binary.yaml").write_bytes(bytes(range(256)) * 8)
    (T / "maybe.yaml").write_text("mixed: maybe\n")
    (T / "binexp").mkdir()
    for table in (
        "runs",
        "evaluations",
        "training_phases",
        "checkpoints",
    ):  # an "export" of binary files
        (T / "binexp" / f"{table}.csv").write_bytes(bytes(range(256)) * 4)
    shipped = (
        Path(__file__).resolve().parents[2]
        / "plugins"
        / "robots"
        / "kuafu"
        / "policies"
        / "flat.pt"
    )
    shutil.copy(shipped.with_name("flat-mixed.pt"), T / "mixed.pt")
    state = torch.load(shipped, map_location="cpu", weights_only=True)
    state["robot"] = "another-robot"
    torch.save(state, T / "other-robot.pt")
    return T


@pytest.mark.parametrize("argv, env", [(c[1], c[2]) for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_and_exit_2(folder, capsys, monkeypatch, argv, env):
    monkeypatch.delenv("COADAPT_STORE", raising=False)
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    args = [a.replace("{T}", str(folder)) for a in argv]
    capsys.readouterr()
    t0 = time.perf_counter()
    code = main(args)
    seconds = time.perf_counter() - t0
    captured = capsys.readouterr()
    lines = [line for line in captured.err.splitlines() if line.strip()]
    assert "Traceback" not in captured.err + captured.out
    assert code == 2, (code, captured.err[-2000:])
    assert len(lines) == 1 and lines[0].startswith("error"), captured.err
    assert seconds < 30
    if args[0] == "grid":  # refused before any cell started: no run folder, no cell log
        out = Path(args[args.index("--out") + 1])
        assert not (out.is_dir() and any(p.name != "grid-logs" for p in out.iterdir()))


@pytest.mark.parametrize(
    "text, expected",
    [('"false"', False), ("false", False), ("no", False), ('"true"', True), ("yes", True)],
)
def test_yaml_booleans_mean_what_they_say(tmp_path, text, expected):
    from coadapt_core.coadapt.config_loading import make_config

    (tmp_path / "c.yaml").write_text(f"mixed: {text}\nmeasure_surrogate_error: {text}\n")
    config = make_config("smoke", tmp_path / "c.yaml", {})
    assert config.mixed is expected and config.measure_surrogate_error is expected
