"""A run's numerics on record (issue 61): the learner's precision in force, the device and its
kind, torch's and the physics engine's versions, said in one line (`coadapt run`) and in a
table cell (`coadapt report`); a learner that reports none, or an engine not declared, is
said so, never guessed."""

from __future__ import annotations

import importlib.metadata

import pytest

from coadapt_core.numerics import (
    NOT_RECORDED,
    distribution_version,
    numerics_cell,
    numerics_text,
    processor_name,
    run_numerics,
)


class Learner:
    """A backend reporting its numerics as `UniversalPolicyBackend.numerics` does."""

    def __init__(self, precision: str):
        self.precision = precision

    def numerics(self) -> dict[str, str]:
        return {
            "precision": self.precision,
            "pseudo_precision": "float32",
            "rollout_precision": "float32",
            "device": "cpu",
        }


class Engine:
    name = "mujoco"
    engine = "mujoco"


class Undeclared:
    name = "mysim"
    engine = ""


def test_a_run_records_the_precision_its_learner_reports_and_the_versions_installed():
    torch = pytest.importorskip("torch")
    n = run_numerics(Learner("float32"), Engine, "cpu")
    assert (n["precision"], n["pseudo_precision"], n["rollout_precision"]) == ("float32",) * 3
    assert n["device"] == "cpu" and n["processor"] == processor_name() != ""
    assert n["torch"] == importlib.metadata.version("torch")
    assert n["torch"].split("+")[0] == torch.__version__.split("+")[0]
    assert n["engine_version"] == importlib.metadata.version("mujoco")
    assert n["threads"] == torch.get_num_threads()
    # whether "auto" would give bf16 here: what torch says of this CPU
    assert n["bf16_native"] is bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())
    text = numerics_text(n)
    assert text.startswith("float32 learner (pseudo-critics float32, rollouts float32) on CPU ")
    assert f"torch {n['torch']}, mujoco {n['engine_version']}" in text
    assert numerics_cell(n) == (
        f"float32 learner, CPU {processor_name()}, torch {n['torch']}, mujoco {n['engine_version']}"
    )


def test_what_is_not_known_is_said_so():
    n = run_numerics(object(), Undeclared, "cpu")  # no numerics(), an engine not declared
    assert n["precision"] is None and n["engine"] is None and n["engine_version"] is None
    text = numerics_text(n)
    assert text.startswith("learner precision not reported on CPU ")
    assert "mysim (engine version not declared)" in text
    assert numerics_text(None) == NOT_RECORDED and numerics_cell({}) == "not recorded"
    assert distribution_version("no-such-distribution-xyz") is None
    assert distribution_version("") is None


def test_the_processor_is_the_cpus_model_name(tmp_path, monkeypatch):
    import coadapt_core.numerics as numerics

    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor\t: 0\nvendor_id\t: AuthenticAMD\nmodel name\t: AMD  EPYC 9B14\n")
    real_path = numerics.Path
    monkeypatch.setattr(
        numerics, "Path", lambda p: cpuinfo if p == "/proc/cpuinfo" else real_path(p)
    )
    assert processor_name() == "AMD EPYC 9B14"
    monkeypatch.setattr(numerics, "Path", lambda p: tmp_path / "none")  # no /proc: the platform's
    assert processor_name() != ""
