"""`coadapt dashboard` without a browser: bad input is one line and exit 2, the store is read
read-only (byte-identical after use, readable while a run writes), no file outside a run
folder is served whatever the URL or the store says, and the JSON holds the report's numbers."""

from __future__ import annotations

import hashlib
import json
import socket
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from coadapt_core.analysis.facts import run_facts
from coadapt_core.analysis.table_markdown import cell
from coadapt_core.analysis.tables import table6_rows
from coadapt_core.cli import main
from coadapt_core.numerics import NOT_RECORDED
from coadapt_core.results import ResultsStore
from tests.core.test_dashboard_support import PAYLOAD, Served, add_run

ROOT = Path(__file__).resolve().parents[2]
RUN = "20261201-100000-ours-pso-torque-s0-aaaaaa"
SUMMARY = {
    "best_design": [0.612, 0.587],
    "best_cost": 1.0123,
    "best_cost_se": 0.004,
    "nominal_cost": 1.155,
    "nominal_cost_se": 0.005,
    "final_interactions": 5000,
    "improvement": 0.1234,
    "improvement_se": 0.0081,
    "fall_rate_difference": 0.016,
    "fall_rate_difference_se": 0.005,
}


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def small(tmp_path):
    """(store file, runs folder) with one finished run and the run folder it names."""
    runs = tmp_path / "runs"
    with ResultsStore(tmp_path / "s.db") as store:
        add_run(store, RUN, runs, summary=SUMMARY)
        (runs / RUN / "notes.txt").write_text("inside")
        (tmp_path / "secret.txt").write_text("SECRET-CONTENT")
        (runs / RUN / "link.txt").symlink_to(tmp_path / "secret.txt")
        # a hostile row: its run_dir points at a folder that is not named after the run
        add_run(store, "20261201-110000-ours-pso-torque-s1-bbbbbb", tmp_path / "elsewhere")
        store.create_run(
            {"method": "ours", "seed": 1},
            run_id="20261201-110000-ours-pso-torque-s1-bbbbbb",
            run_dir=str(tmp_path),
        )
    return tmp_path / "s.db", runs


def one_line_error(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    return lines[0]


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--port", "70000"], "port"),
        (["--port", "abc"], "port"),
        (["--store", "bad://x"], "store"),
        (["--store", "/no/such/folder/s.db"], "does not exist"),
        (["--runs", "/no/such/runs"], "--runs"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(args, words, small, capsys):
    store, _ = small
    full = ["dashboard", *(["--store", str(store)] if "--store" not in args else []), *args]
    assert main(full) == 2
    assert words in one_line_error(capsys)


def test_a_store_that_is_not_there_or_not_a_store_is_one_line(tmp_path, capsys):
    missing = tmp_path / "missing.db"
    assert main(["dashboard", "--store", str(missing)]) == 2
    assert "no such file" in one_line_error(capsys)
    assert not missing.exists()  # reading must not leave an empty store behind
    text = tmp_path / "notes.db"
    text.write_text("not a database at all " * 100)
    assert main(["dashboard", "--store", str(text)]) == 2
    assert "cannot be used" in one_line_error(capsys)
    assert text.read_text().startswith("not a database")


def test_a_port_in_use_is_one_line(small, capsys):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert main(["dashboard", "--store", str(small[0]), "--port", str(port)]) == 2
    assert "in use" in one_line_error(capsys)


def test_another_address_only_when_asked_and_it_says_so(small):
    command = [sys.executable, "-m", "coadapt_core", "dashboard", "--store", str(small[0])]
    proc = subprocess.Popen(
        [*command, "--host", "0.0.0.0", "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    try:
        first = proc.stdout.readline()
        warning = proc.stderr.readline()
    finally:
        proc.terminate()
        proc.wait(timeout=20)
    assert first.startswith("dashboard: http://0.0.0.0:")
    assert "not only this machine" in warning


def test_binds_127_0_0_1_by_default_and_refuses_other_host_names(small):
    served = Served(small[0])
    try:
        assert served.server.server_address[0] == "127.0.0.1"
        import http.client

        connection = http.client.HTTPConnection(*served.server.server_address[:2], timeout=10)
        connection.request("GET", "/api/runs", headers={"Host": "evil.example:80"})
        assert connection.getresponse().status == 403
    finally:
        served.close()


HOSTILE = [
    "/files/{run}/../../s.db",
    "/files/{run}/..%2F..%2Fs.db",
    "/files/{run}/%2e%2e/%2e%2e/s.db",
    "/files/{run}//etc/passwd",
    "/files/{run}/%2Fetc%2Fpasswd",
    "/files/{run}/link.txt",  # a link inside the folder that leads out of it
    "/files/{run}/checkpoints/../../../secret.txt",
    "/files/..%2F..%2Fsecret.txt/x.txt",
    "/files/20261201-110000-ours-pso-torque-s1-bbbbbb/secret.txt",  # run_dir not its folder
    "/static/../readonly.py",
    "/static/%2e%2e%2freadonly.py",
    "//etc/passwd",
]


def test_no_file_outside_a_run_folder_is_served(small):
    served = Served(small[0])
    try:
        status, body = served.get(f"/files/{RUN}/notes.txt")
        assert (status, body) == (200, b"inside")
        status, body = served.get(f"/files/{RUN}/best_vs_nominal.gif")
        assert status == 200 and body.startswith(b"GIF89a")
        for path in HOSTILE:
            status, body = served.get(path.format(run=RUN))
            assert status in (400, 403, 404), path
            assert b"SECRET-CONTENT" not in body and b"SQLite format" not in body, path
            assert b"Traceback" not in body
    finally:
        served.close()


def test_the_store_is_byte_identical_after_use_and_readable_while_a_run_writes(small):
    store_file, _ = small
    before = digest(store_file)
    served = Served(store_file)
    statuses = []
    try:
        for _ in range(3):
            for path in ("/", "/api/runs", f"/api/run/{RUN}", f"/api/compare?run={RUN}"):
                statuses.append(served.get(path)[0])
        assert set(statuses) == {200}
    finally:
        served.close()
    assert digest(store_file) == before
    # a writer adds rows while pages are read: every answer is the page or a one-line 503
    stop = threading.Event()

    def write() -> None:
        with ResultsStore(store_file) as writer:
            outer = 10
            while not stop.is_set():
                row = {"outer": outer, "inner": 0, "idx": 0, "kind": "real", "design": [1, 1]}
                writer.record_evaluations(RUN, [{**row, "costs": {"torque": 1.0}}])
                outer += 1

    thread = threading.Thread(target=write)
    thread.start()
    served = Served(store_file)
    try:
        seen = [served.get(f"/api/run/{RUN}") for _ in range(15)]
    finally:
        stop.set()
        thread.join()
        served.close()
    assert {s for s, _ in seen} <= {200, 503}
    assert sum(s == 200 for s, _ in seen) >= 10
    assert all(b"Traceback" not in body for _, body in seen)


def test_the_json_holds_the_reports_numbers(small):
    store_file, _ = small
    served = Served(store_file)
    try:
        data = json.loads(served.get(f"/api/run/{RUN}")[1])
        with ResultsStore(store_file, create=False) as store:
            row = table6_rows([run_facts(store, store.get_run(RUN))])[0]
    finally:
        served.close()
    assert data["report"]["improvement"] == cell(row, "improvement", pct=True)
    assert data["report"]["improvement"] == "12.3% ± 0.8% SE (n=1)"
    # a difference of two fall rates is in points, signed, as the CLI says it
    assert data["report"]["fall_rate_difference"] == "+1.6 ± 0.5 points SE (n=1)"
    assert data["report"]["best_design"] == [
        ["thigh_scale", "0.612 (n=1)"],
        ["shank_scale", "0.587 (n=1)"],
    ]
    assert data["counts"] == {"real": 16, "surrogate": 4}
    assert data["files"] == ["best_vs_nominal.gif"]
    assert data["numerics"] == NOT_RECORDED  # a summary from before numerics were recorded
    # the convergence chart as the run folder's convergence.png: the cost's unit on its axis,
    # the final check +- SE after the curve by its own interactions, the nominal line
    convergence = data["convergence"]
    assert convergence["y_label"] == "torque cost per step [(Nm)^2]"
    assert convergence["final"] == {
        "cost": 1.0123,
        "se": 0.004,
        "interactions": 5000,
        "nominal": 1.155,
        "nominal_se": 0.005,
    }
    assert convergence["x"][-1] == 2 * 10_000 + 16 * 1000  # training steps + real evaluations
    # what the learner measured: one chart per unit, each phase's values
    assert [(m["unit"], [k for k, _ in m["series"]]) for m in data["training_measures"]] == [
        ("m/s", ["vx", "tracking_error"]),
        ("s", ["episode_length_s"]),
    ]
    assert [t["vx"] for t in data["training"]] == pytest.approx([0.35, 0.45])
    assert [t["episode_length_s"] for t in data["training"]] == [8.0, 12.0]


def test_unknown_runs_and_hostile_ids_are_one_line_not_a_traceback(small):
    served = Served(small[0])
    try:
        for path in (
            "/api/run/20990101-000000-nope-aaaaaa",
            "/api/run/%3Cscript%3E",
            "/api/grid/x",
        ):
            status, body = served.get(path)
            assert status == 404
            assert "error" in json.loads(body)
        status, body = served.get("/nothing/here")
        assert status == 404 and b"<script" not in body
        status, body = served.get("/run/%3Cscript%3Ealert(1)%3C%2Fscript%3E")
        assert status == 200 and b"<script>alert" not in body  # the shell names no id
        assert PAYLOAD.encode() not in body
    finally:
        served.close()


def test_the_dashboard_room_only_reads():
    """No module of coadapt_core/dashboard calls a store method that writes, imports the
    learner, physics, the task or the experiments, or opens a file to write."""
    import ast

    writes = {"record_evaluations", "record_training", "record_checkpoint", "create_run"}
    writes |= {"finish_run", "set_status", "save_grid", "set_cell", "write_text", "write_bytes"}
    forbidden = ("learning", "physics", "task", "experiments", "coadapt.")
    found = []
    for path in (ROOT / "coadapt_core" / "dashboard").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Attribute) and node.attr in writes:
                found.append(f"{path.name}:{node.lineno} .{node.attr}")
            module = node.module if isinstance(node, ast.ImportFrom) else None
            if module and any(module.startswith(f"coadapt_core.{f}") for f in forbidden):
                found.append(f"{path.name}:{node.lineno} imports {node.module}")
            if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "open":
                found.append(f"{path.name}:{node.lineno} open()")
    assert found == []
