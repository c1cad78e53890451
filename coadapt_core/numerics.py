"""Which numerics a run trained and evaluated with: the learner's precision actually in force
(bf16 or float32: `TrainConfig.precision` "auto" resolves to bf16 where the device computes it
natively), the device and its kind (the CPU's model name or the GPU's), and the torch and
physics-engine versions. A run's answer moves with these (README, "The first run"), so every
run's summary records them (`summary.json`'s "numerics", the store's summary column) and
`coadapt run` and `coadapt report` say them."""

from __future__ import annotations

import importlib.metadata
import platform
import sys
from pathlib import Path
from typing import Any

#: what a summary written before the numerics were recorded says in their place
NOT_RECORDED = "not recorded (a run before numerics were recorded)"


def processor_name() -> str:
    """The CPU's model name (/proc/cpuinfo's "model name", else the platform's word)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            if key.strip() in ("model name", "Model", "cpu model") and value.strip():
                return " ".join(value.split())
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown CPU"


def distribution_version(name: str) -> str | None:
    """The installed version of a Python distribution (its pip name), None when absent."""
    if not name:
        return None
    try:
        return importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        return None


def device_numerics(device: str) -> dict[str, Any]:
    """The device a learner computes on: its type, its kind (CPU model or GPU name) and
    whether it computes bfloat16 natively (what "auto" precision asks; None where torch was
    never loaded: a run without a torch learner)."""
    kind = device.split(":")[0] or "cpu"
    torch = sys.modules.get("torch")
    if torch is None:
        return {"device": kind, "processor": processor_name(), "bf16_native": None}
    if kind == "cuda" and torch.cuda.is_available():
        name = torch.cuda.get_device_name(torch.device(device))
        native = bool(torch.cuda.is_bf16_supported())
    else:
        name = processor_name()
        native = bool(
            kind == "cpu"
            and torch.backends.mkldnn.is_available()
            and torch.ops.mkldnn._is_mkldnn_bf16_supported()
        )
    return {"device": kind, "processor": name, "bf16_native": native}


def run_numerics(backend: Any, simulator_cls: type | None, device: str = "cpu") -> dict[str, Any]:
    """The numerics of a run: what its learner reports (`numerics()` of the backend, where it
    has one: "precision" of the PPO loss, "pseudo_precision" of the pseudo-critics,
    "rollout_precision" of the policy in rollouts, "device"), the device's kind, torch's
    version and the simulator's engine and version (`Simulator.engine`). Imports no torch
    that the run did not."""
    report = getattr(backend, "numerics", None)
    learned = dict(report() or {}) if callable(report) else {}
    engine = str(getattr(simulator_cls, "engine", "") or "")
    torch = sys.modules.get("torch")
    return {
        "precision": learned.get("precision"),
        "pseudo_precision": learned.get("pseudo_precision"),
        "rollout_precision": learned.get("rollout_precision"),
        **device_numerics(str(learned.get("device") or device)),
        "threads": torch.get_num_threads() if torch is not None else None,
        "torch": distribution_version("torch"),
        "simulator": getattr(simulator_cls, "name", None),
        "engine": engine or None,
        "engine_version": distribution_version(engine),
        "python": platform.python_version(),
    }


def simulated_numerics(backend: Any, simulator: str, device: str = "cpu") -> dict[str, Any]:
    """`run_numerics` of a run on the simulator plugin named `simulator` (None for the
    class where the registry holds no such plugin: a test's own)."""
    from coadapt_core.plugins import get_registry

    try:
        simulator_cls = get_registry().get("simulator", simulator)
    except Exception:
        simulator_cls = None
    return run_numerics(backend, simulator_cls, device)


def numerics_text(numerics: dict[str, Any] | None) -> str:
    """The numerics in one line: "bf16 learner (pseudo-critics bf16, rollouts float32) on
    CPU AMD EPYC (bf16 native), 2 threads; torch 2.13.0, mujoco 3.3.7"."""
    if not numerics:
        return NOT_RECORDED
    n = numerics
    if n.get("precision"):
        learner = f"{n['precision']} learner"
        inner = [
            f"pseudo-critics {n['pseudo_precision']}" if n.get("pseudo_precision") else "",
            f"rollouts {n['rollout_precision']}" if n.get("rollout_precision") else "",
        ]
        if any(inner):
            learner += f" ({', '.join(p for p in inner if p)})"
    else:
        learner = "learner precision not reported"
    where = f"{str(n.get('device') or '?').upper()} {n.get('processor') or '?'}"
    native = {True: " (bf16 native)", False: " (no native bf16)"}.get(n.get("bf16_native"), "")
    threads = n.get("threads")
    where += native + (f", {threads} thread{'s' if threads != 1 else ''}" if threads else "")
    versions = [f"torch {n.get('torch') or '?'}"]
    if n.get("engine"):
        versions.append(f"{n['engine']} {n.get('engine_version') or '?'}")
    elif n.get("simulator"):
        versions.append(f"{n['simulator']} (engine version not declared)")
    return f"{learner} on {where}; {', '.join(versions)}"


def numerics_cell(numerics: dict[str, Any] | None) -> str:
    """The numerics in a table cell: "bf16 learner, CPU AMD EPYC, torch 2.13.0, mujoco 3.3.7"
    ("not recorded" for a run before they were)."""
    if not numerics:
        return "not recorded"
    n = numerics
    parts = [
        f"{n.get('precision') or '?'} learner",
        f"{str(n.get('device') or '?').upper()} {n.get('processor') or '?'}",
        f"torch {n.get('torch') or '?'}",
    ]
    if n.get("engine"):
        parts.append(f"{n['engine']} {n.get('engine_version') or '?'}")
    return ", ".join(parts)


__all__ = [
    "NOT_RECORDED",
    "device_numerics",
    "distribution_version",
    "numerics_cell",
    "numerics_text",
    "processor_name",
    "run_numerics",
    "simulated_numerics",
]
