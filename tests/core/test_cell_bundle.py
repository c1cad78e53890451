"""What a Ray grid cell hands back (`coadapt_core.experiments.cell_bundle`): a run folder as
bytes and its store rows, unpacked on the driver with every name and size checked, and a
node with another coadapt or plugin set refusing the cell (`ray_cell`)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from coadapt_core.experiments.cell import Cell
from coadapt_core.experiments.cell_bundle import (
    BundleError,
    Limits,
    export_rows,
    import_rows,
    pack_folder,
    retarget_state,
    write_folder,
)
from coadapt_core.experiments.grid_plan import CellTask
from coadapt_core.experiments.ray_cell import (
    REFUSED,
    RayCell,
    fingerprint_difference,
    node_fingerprint,
    run_cell,
)
from coadapt_core.results import ResultsStore


def _folder(root: Path) -> Path:
    folder = root / "r-abc123"
    (folder / "checkpoints").mkdir(parents=True)
    (folder / "summary.json").write_text('{"best_cost": 1.5}')
    (folder / "checkpoints" / "backend-outer0.pt").write_bytes(b"\x00" * 1000)
    (folder / "buffer-3.npz").write_bytes(b"buffer")
    (folder / "state.json").write_text(
        json.dumps({"config": {"store": "sqlite:///cell.db", "out": "runs"}})
    )
    os.symlink("/etc/passwd", folder / "link")
    return folder


def test_a_folder_round_trips_without_its_buffer_and_links(tmp_path):
    files = pack_folder(_folder(tmp_path))
    assert sorted(files) == ["checkpoints/backend-outer0.pt", "state.json", "summary.json"]
    assert "buffer-3.npz" in pack_folder(tmp_path / "r-abc123", keep_buffer=True)
    dest = write_folder(files, tmp_path / "out" / "r-abc123")
    assert (dest / "checkpoints" / "backend-outer0.pt").read_bytes() == b"\x00" * 1000
    assert not (dest / "link").exists() and not (dest / "buffer-3.npz").exists()
    (dest / "stale.txt").write_text("x")
    write_folder(files, dest)  # a newer copy replaces the folder as a whole
    assert not (dest / "stale.txt").exists() and not list(dest.parent.glob(".incoming-*"))


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("../escape", "'..'"),
        ("a/../../escape", "'..'"),
        ("/etc/cron.d/x", "absolute"),
        ("a//b", "empty part"),
        ("a\\b", "not a relative path"),
        ("", "not a relative path"),
    ],
)
def test_a_name_leaving_the_folder_writes_nothing(tmp_path, name, message):
    with pytest.raises(BundleError, match=message):
        write_folder({"ok.txt": b"1", name: b"2"}, tmp_path / "out" / "r-abc123")
    assert not (tmp_path / "out" / "r-abc123").exists() and not (tmp_path / "escape").exists()


def test_caps_and_a_link_in_place_of_the_folder_are_refused(tmp_path):
    small = Limits(files=2, file_bytes=10, total_bytes=15)
    with pytest.raises(BundleError, match="over the cap of 10"):
        write_folder({"a": b"x" * 11}, tmp_path / "r1", limits=small)
    with pytest.raises(BundleError, match="over 15 bytes"):
        write_folder({"a": b"x" * 8, "b": b"x" * 8}, tmp_path / "r1", limits=small)
    with pytest.raises(BundleError, match="more than 2 files"):
        write_folder({"a": b"", "b": b"", "c": b""}, tmp_path / "r1", limits=small)
    with pytest.raises(BundleError, match="not bytes"):
        write_folder({"a": "text"}, tmp_path / "r1")
    os.symlink(tmp_path, tmp_path / "r2")
    with pytest.raises(BundleError, match="is a link"):
        write_folder({"a": b""}, tmp_path / "r2")


def test_rows_are_merged_with_the_folder_the_driver_chose(tmp_path):
    worker = ResultsStore(tmp_path / "worker.db")
    scratch = tmp_path / "scratch" / "runs" / "r-abc123"
    worker.create_run(
        {"method": "ours", "objective": "torque", "seed": 0, "grid_cell": "cell-a"},
        run_id="r-abc123",
        run_dir=str(scratch),
    )
    worker.record_checkpoint(
        "r-abc123", outer=0, path=str(scratch / "checkpoints" / "backend-outer0.pt")
    )
    worker.finish_run("r-abc123", {"best_cost": 1.5})
    rows = export_rows(worker, ["r-abc123"])
    driver = ResultsStore(tmp_path / "driver.db")
    here = tmp_path / "out" / "r-abc123"
    result = import_rows(driver, rows, run_id="r-abc123", folder=here, cell="cell-a")
    assert result.added == ["r-abc123"] and result.rows["checkpoints"] == 1
    run = driver.get_run("r-abc123")
    assert run["run_dir"] == str(here.resolve()) and run["status"] == "finished"
    assert [c["path"] for c in driver.checkpoints("r-abc123")] == [
        str(here.resolve() / "checkpoints/backend-outer0.pt")
    ]
    assert import_rows(driver, rows, run_id="r-abc123", folder=here).skipped == [
        "r-abc123"
    ]  # the merge rule
    with pytest.raises(BundleError, match="not just r-other"):
        import_rows(driver, rows, run_id="r-other", folder=here)
    with pytest.raises(BundleError, match="not a run of cell cell-b"):
        import_rows(driver, rows, run_id="r-abc123", folder=here, cell="cell-b")
    with pytest.raises(BundleError, match="not the tables"):
        import_rows(driver, {"runs": rows["runs"]}, run_id="r-abc123", folder=here)


def test_the_state_names_the_store_and_folder_of_its_machine(tmp_path):
    folder = _folder(tmp_path)
    assert retarget_state(folder, out="/data/runs", store="sqlite:////data/coadapt.db")
    config = json.loads((folder / "state.json").read_text())["config"]
    assert config == {"store": "sqlite:////data/coadapt.db", "out": "/data/runs"}
    assert not retarget_state(tmp_path, out="x", store="y")  # no state there


def test_a_node_with_other_plugins_refuses_the_cell_in_one_line():
    mine = node_fingerprint()
    assert mine["plugins"] and fingerprint_difference(mine, dict(mine)) is None
    other = {**mine, "plugins": [*mine["plugins"], "robot:walker=walker-robots 0.3"]}
    assert (
        fingerprint_difference(other, mine)
        == "plugins differ (only on the driver: robot:walker=walker-robots 0.3)"
    )
    assert fingerprint_difference({**mine, "coadapt": "0.0.1"}, mine).startswith("coadapt ")
    cell = Cell("ours", "torque", "flat", 0, "smoke", "mujoco")
    task = CellTask(cell=cell, argv=[], env={}, command=None, log_path=None)
    result = run_cell(RayCell(task=task, extra=[], fingerprint=other))
    outcome = result["outcome"]
    assert outcome.returncode == REFUSED and "\n" not in outcome.error
    assert outcome.error.startswith("node ") and "refused the cell: plugins differ" in outcome.error


def test_a_cells_reservation_is_its_threads_and_a_gpu_for_cuda():
    from coadapt_core.experiments.grid_ray import cell_gpus, cell_threads

    assert cell_threads(["run", "--seed", "0", "--threads", "4", "--json"]) == 4
    assert cell_threads(["run", "--threads=3"]) == 3 and cell_threads(["run", "--seed", "2"]) == 1
    assert (
        cell_gpus(["run", "--device", "cuda"]) == 1 and cell_gpus(["run", "--device=cuda:1"]) == 1
    )
    assert cell_gpus(["run", "--device", "cpu"]) == 0 and cell_gpus(["run"]) == 0
