"""Sim-to-sim: the same robot and policy on a second simulator.

Policy transfer (`transfer_runs`, Table 6's last column): the run's final universal policy
evaluates its best and its nominal design on another simulator under the one sim-to-sim
protocol (`coadapt_core.sim_to_sim`, which `coadapt handoff` follows too: `evaluate_pair`);
the figures are written to the store as rows of kind "sim2sim", which `coadapt report`
reads. A run whose rows exist is not evaluated again.

Backend check (`compare_backends`): do two simulator backends move the same robot the same
way? The same open-loop joint-target sequence from the same initial state, randomization
off, on two backends, for a few designs; the first second is compared:

1. swing — base welded in the air (`fixed_base=True`), sinusoidal targets on every
   actuated joint: joint position, velocity and torque trajectories (no contact, so this
   isolates masses, inertias, frames, armature, damping, actuation and integration);
2. standing — on flat ground holding the default pose: base height, base orientation and
   joint positions (adds the contact models).

`python -m coadapt_core.experiments.transfer ROBOT REFERENCE OTHER` prints the backend
check's figures as the Markdown tables of docs/sim-to-sim.md.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core import sim_to_sim as sim2sim
from coadapt_core.costs import CostRule
from coadapt_core.errors import BackendUnavailable, CoadaptError, UserError
from coadapt_core.experiments.own_policies import (
    each_own_policy,
    nominal_of,
    policy_files,
    run_backend,
    run_objectives,
    shares_policy,
)
from coadapt_core.fitness import CoadaptationBackend
from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.physics.simulator import Simulator
from coadapt_core.results.recorders import batch_rows
from coadapt_core.results.rows import best_of, checkpoint_of
from coadapt_core.results.schema import TRANSFER_KIND, TRANSFER_OUTER
from coadapt_core.results.store import ResultsStore
from coadapt_core.robot import Robot

#: designs the check runs by default: nominal, both extremes, a mixed one
DEFAULT_DESIGNS = ((1.0, 1.0), (0.5, 0.5), (1.5, 1.5), (0.7, 1.3))
#: swing test: per joint (amplitude rad, frequency Hz), repeated over legs of 4 joints
SWING_AMPLITUDE = (0.2, 0.4, 0.5, 0.3)
SWING_FREQUENCY = (1.0, 1.5, 2.0, 2.5)


@dataclass
class ErrorFigure:
    """Difference between the backends in one quantity over time (and joints)."""

    rms: float
    max: float

    @classmethod
    def of(cls, a: np.ndarray, b: np.ndarray) -> ErrorFigure:
        diff = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
        return cls(rms=float(np.sqrt(np.mean(diff**2))), max=float(np.max(np.abs(diff))))


@dataclass
class DesignFigures:
    """Figures for one design. Swing: joint_pos (rad), joint_vel (rad/s), joint_torque
    (N m). Standing: base_height (m), orientation (rad, angle between the base
    orientations), joint_pos (rad); plus each backend's base height drop over the run."""

    design: tuple[float, ...]
    swing: dict[str, ErrorFigure] = field(default_factory=dict)
    standing: dict[str, ErrorFigure] = field(default_factory=dict)
    height_drop: dict[str, float] = field(default_factory=dict)  # backend -> m
    swing_amplitude: float = 0.0  # rad, RMS of joint motion (scale for the errors)

    def to_dict(self) -> dict:
        return {
            "design": list(self.design),
            "swing": {k: vars(v) for k, v in self.swing.items()},
            "standing": {k: vars(v) for k, v in self.standing.items()},
            "height_drop": dict(self.height_drop),
            "swing_amplitude": self.swing_amplitude,
        }


def swing_targets(default_joint_pos: np.ndarray, steps: int, control_dt: float) -> np.ndarray:
    """[steps, N, J] sinusoidal targets around each environment's default pose [N, J]."""
    default_joint_pos = np.atleast_2d(default_joint_pos)
    j = default_joint_pos.shape[1]
    amp = np.resize(np.asarray(SWING_AMPLITUDE), j)
    # the two legs move at different frequencies so they are not mirror images
    freq = np.resize(np.asarray(SWING_FREQUENCY), j) * np.repeat([1.0, 1.2], (j + 1) // 2)[:j]
    t = (np.arange(steps) + 1) * control_dt
    wave = amp * np.sin(2 * np.pi * freq * t[:, None])  # [steps, J]
    return default_joint_pos[None] + wave[:, None, :]


def _make(
    sim_cls: type[Simulator], robot: Robot, designs: np.ndarray, *, fixed_base: bool, **kwargs
) -> Simulator:
    return sim_cls(
        robot,
        designs,
        terrain="flat",
        randomization=RandomizationConfig.off(),
        seed=0,
        fixed_base=fixed_base,
        **kwargs,
    )


def _roll(sim: Simulator, targets: np.ndarray | None, steps: int) -> dict[str, np.ndarray]:
    """Reset, then `steps` policy steps; stacked [steps + 1, N, ...] trajectories."""
    state = sim.reset()
    keys = ("joint_pos", "joint_vel", "joint_torque", "base_pos", "base_quat")
    out = {k: [getattr(state, k).double().cpu().numpy()] for k in keys}
    hold = sim.default_joint_pos
    for i in range(steps):
        state = sim.step(hold if targets is None else targets[i])
        if bool(state.diverged.any()):
            raise RuntimeError(f"{sim.name}: physics diverged during the sim-to-sim check")
        for k in keys:
            out[k].append(getattr(state, k).double().cpu().numpy())
    return {k: np.stack(v) for k, v in out.items()}


def _orientation_error(qa: np.ndarray, qb: np.ndarray) -> np.ndarray:
    """Angle (rad) between unit quaternions [..., 4]."""
    dot = np.clip(np.abs(np.sum(qa * qb, axis=-1)), 0.0, 1.0)
    return 2.0 * np.arccos(dot)


def _resolve(sim: str | type[Simulator]) -> type[Simulator]:
    if isinstance(sim, str):
        from coadapt_core.plugins import get_registry

        return get_registry().get("simulator", sim)
    return sim


def compare_backends(
    robot: Robot,
    designs: np.ndarray | None = None,
    *,
    reference: str | type[Simulator],
    other: str | type[Simulator],
    duration: float = 1.0,
    physics_dt: float = 0.005,
    decimation: int = 4,
    other_kwargs: dict | None = None,
) -> list[DesignFigures]:
    """Swing and standing figures per design (`DEFAULT_DESIGNS` when None), `other`
    measured against `reference`. Each backend simulates all designs as one batch."""
    designs = np.atleast_2d(
        np.asarray(DEFAULT_DESIGNS if designs is None else designs, dtype=float)
    )
    ref_cls, other_cls = _resolve(reference), _resolve(other)
    steps = round(duration / (physics_dt * decimation))
    runs: dict[str, dict[str, dict[str, np.ndarray]]] = {"swing": {}, "standing": {}}
    for label, cls, extra in (("reference", ref_cls, {}), ("other", other_cls, other_kwargs or {})):
        common = {"physics_dt": physics_dt, "decimation": decimation, **extra}
        with _make(cls, robot, designs, fixed_base=True, **common) as sim:
            targets = swing_targets(
                sim.default_joint_pos.double().cpu().numpy(), steps, sim.control_dt
            )
            runs["swing"][label] = _roll(sim, targets, steps)
        with _make(cls, robot, designs, fixed_base=False, **common) as sim:
            runs["standing"][label] = _roll(sim, None, steps)
    figures = []
    sw_ref, sw_other = runs["swing"]["reference"], runs["swing"]["other"]
    st_ref, st_other = runs["standing"]["reference"], runs["standing"]["other"]
    for i, design in enumerate(designs):
        fig = DesignFigures(design=tuple(float(x) for x in design))
        for key in ("joint_pos", "joint_vel", "joint_torque"):
            # torque is the mean over the step that ends at a sample: skip the reset sample
            start = 1 if key == "joint_torque" else 0
            fig.swing[key] = ErrorFigure.of(sw_other[key][start:, i], sw_ref[key][start:, i])
        motion = sw_ref["joint_pos"][:, i] - sw_ref["joint_pos"][0, i]
        fig.swing_amplitude = float(np.sqrt(np.mean(motion**2)))
        fig.standing["base_height"] = ErrorFigure.of(
            st_other["base_pos"][:, i, 2], st_ref["base_pos"][:, i, 2]
        )
        angle = _orientation_error(st_other["base_quat"][:, i], st_ref["base_quat"][:, i])
        fig.standing["orientation"] = ErrorFigure.of(angle, np.zeros_like(angle))
        fig.standing["joint_pos"] = ErrorFigure.of(
            st_other["joint_pos"][:, i], st_ref["joint_pos"][:, i]
        )
        for label, run in (("reference", st_ref), ("other", st_other)):
            fig.height_drop[label] = float(run["base_pos"][0, i, 2] - run["base_pos"][-1, i, 2])
        figures.append(fig)
    return figures


def markdown_tables(figures: list[DesignFigures]) -> str:
    """The figures as Markdown, one table per design."""
    lines = []
    for fig in figures:
        lines.append(f"#### Design ({', '.join(f'{x:g}' for x in fig.design)})")
        lines.append("")
        lines.append("| test | quantity | RMS error | max error |")
        lines.append("|---|---|---|---|")
        units = {
            "joint_pos": "rad",
            "joint_vel": "rad/s",
            "joint_torque": "N m",
            "base_height": "m",
            "orientation": "rad",
        }
        for test, table in (("swing", fig.swing), ("standing", fig.standing)):
            for key, err in table.items():
                lines.append(f"| {test} | {key} ({units[key]}) | {err.rms:.4f} | {err.max:.4f} |")
        lines.append("")
        lines.append(
            f"Swing joint motion RMS {fig.swing_amplitude:.3f} rad; "
            "standing base height drop over 1 s: "
            f"reference {fig.height_drop['reference'] * 100:.2f} cm, "
            f"other {fig.height_drop['other'] * 100:.2f} cm."
        )
        lines.append("")
    return "\n".join(lines)


# -- policy transfer (Table 6's last column) ----------------------------------------------------
#: builds a run's backend: `coadapt_core.learning.factory.make_backend`'s signature
BackendFactory = Callable[..., CoadaptationBackend]


def run_checkpoint_in_store(store: ResultsStore, run: dict[str, Any]) -> tuple[Path | None, str]:
    """The run's final policy checkpoint as its store rows name it, resolved inside the
    run's own folder, or (None, why not). A store row is never trusted as a path: paths
    relative to the folder a run was started from (older rows) are looked up inside the run
    folder by their last two parts."""
    checkpoints = store.checkpoints(run["id"])
    recorded = (run.get("summary") or {}).get("checkpoint") or (
        checkpoints[-1]["path"] if checkpoints else None
    )
    if recorded is None:
        return None, "n/a: the run recorded no policy checkpoint"
    found = checkpoint_of(run, recorded)
    if found is None and not Path(str(recorded)).is_absolute():
        parts = Path(str(recorded)).parts
        if len(parts) >= 2 and parts[-2] == "checkpoints":
            found = checkpoint_of(run, str(Path(*parts[-2:])))
    if found is None:
        return None, "n/a: the recorded checkpoint is not inside the run's folder (refused)"
    if not found.exists():
        return None, f"n/a: checkpoint {found} is gone"
    return found, ""


def transfer_rows(store: ResultsStore, run_id: str, simulator: str) -> list:
    """The run's transfer rows on `simulator` (idx 0 best design, 1 nominal)."""
    return [e for e in store.evaluations(run_id, kind=TRANSFER_KIND) if e.simulator == simulator]


def transfer_run(
    store: ResultsStore,
    run: dict[str, Any],
    best_design: Sequence[float] | None,
    *,
    simulator: str,
    agents: int | None = None,
    steps: int | None = None,
    factory: BackendFactory | None = None,
) -> str:
    """Evaluate `best_design` and the run's nominal design with the run's final policy on
    `simulator` under the sim-to-sim protocol (`sim2sim.protocol_of`: `agents` paired
    scenarios of `steps` steps) and record them (kind "sim2sim", idx 0 best, 1 nominal, the
    protocol's figures), unless the store already holds them. Returns '' when the rows
    exist, else why not ("n/a: ...")."""
    if not run["objectives"] or best_design is None:
        return "n/a: the run has no best design"
    if len(transfer_rows(store, run["id"], simulator)) >= 2:
        return ""
    if run.get("simulator") == simulator:
        return f"n/a: the run itself used {simulator}"
    shared = shares_policy(run)
    checkpoint, why = run_checkpoint_in_store(store, run) if shared else (None, "")
    if shared and checkpoint is None:
        return why
    cfg = run.get("config") or {}
    protocol = sim2sim.protocol_of(cfg, agents, steps)
    best = np.asarray(best_design, dtype=float)

    def make(path: Any) -> CoadaptationBackend:
        return run_backend(run, best.shape[0], simulator, protocol.scenarios, str(path), factory)[0]

    try:
        designs = {"best": best, "nominal": nominal_of(run, best.shape[0])}
        objectives = run_objectives(run, simulator)
        with contextlib.ExitStack() as stack:
            files = (
                {"best": checkpoint, "nominal": checkpoint}
                if shared
                else stack.enter_context(policy_files(run, designs))
            )
            fit = evaluate_pair(
                make, files, designs, objectives, protocol, int(run.get("seed") or 0)
            )
    except BackendUnavailable as exc:
        return f"n/a: {exc}"
    except UserError as exc:  # e.g. a checkpoint that is not one (refused unread): this run only
        return f"n/a: {' '.join(str(exc).split())}"
    store.record_evaluations(
        run["id"],
        batch_rows(
            outer=TRANSFER_OUTER,
            inner=0,
            kind=TRANSFER_KIND,
            designs=[best.tolist(), designs["nominal"].tolist()],
            costs=_rows(fit, objectives, cfg, protocol),
            interactions=fit.interactions // 2,
            seconds=fit.seconds / 2,
            simulator=simulator,
        ),
    )
    return ""


def evaluate_pair(
    make: Callable[[Any], Any],
    files: dict[str, Any],
    designs: dict[str, np.ndarray],
    objectives: Sequence[Any],
    protocol: sim2sim.Protocol,
    run_seed: int,
) -> Any:
    """The paired evaluation of designs["best"] and designs["nominal"] (rows 0 and 1) under
    the protocol: one backend `make(policy file)` when both share the policy (`files` names
    one file for both), else each design under its own on the same scenarios."""
    size = {"agents": protocol.scenarios, "steps": protocol.steps, "seed": protocol.seed(run_seed)}

    def evaluate(backend: Any, rows: np.ndarray) -> list[Any]:
        return [backend.real_fitness(rows, list(objectives), **size)]

    if str(files["nominal"]) != str(files["best"]):
        return each_own_policy(make, files, designs, evaluate)[0]
    backend = make(files["best"])
    try:
        return evaluate(backend, np.stack([designs["best"], designs["nominal"]]))[0]
    finally:
        close = getattr(backend, "close", None)
        if callable(close):
            close()


def _rows(fit: Any, objectives: list, cfg: dict[str, Any], protocol: Any) -> list[dict]:
    """The two stored rows: the protocol's figures, or the costs alone (under the run's rule,
    the nominal design giving the reference level) from a backend without per-scenario costs."""
    rule = CostRule.from_config(cfg)
    rows = sim2sim.figures(fit, objectives, rule, sim2sim.gate_of(cfg), protocol)
    if rows is not None:
        return rows
    costs = rule.costs_of(fit, nominal=1).reshape(2, -1)  # [2, M]
    names = [o.name for o in objectives]
    return [dict(zip(names, row.tolist(), strict=True)) for row in costs]


def transfer_runs(
    store: ResultsStore,
    runs: Sequence[dict[str, Any]],
    *,
    simulator: str,
    agents: int | None = None,
    steps: int | None = None,
    factory: BackendFactory | None = None,
    progress: Callable[[int, int, str], None] | None = None,
) -> dict[str, str]:
    """`transfer_run` for each run's best design (`best_of`); returns run id -> why it has
    no rows (only runs without them). `progress(done, total, what)` hears of each run."""
    return each_best_design(
        store,
        runs,
        "sim-to-sim",
        progress,
        lambda run, best: transfer_run(
            store, run, best, simulator=simulator, agents=agents, steps=steps, factory=factory
        ),
    )


def each_best_design(
    store: ResultsStore,
    runs: Sequence[dict[str, Any]],
    what: str,
    progress: Callable[[int, int, str], None] | None,
    evaluate: Callable[[dict[str, Any], Any], str],
) -> dict[str, str]:
    """`evaluate(run, best design)` for each run (`best_of` its real rows), telling `progress`;
    returns run id -> the note of each run left without rows."""
    notes = {}
    for i, run in enumerate(runs):
        if progress is not None:
            progress(i, len(runs), f"{what} {run['id']}")
        best, _ = best_of(run, store.evaluations(run["id"], kind="real"))
        note = evaluate(run, best)
        if note:
            notes[run["id"]] = note
    if progress is not None:
        progress(len(runs), len(runs), f"{what} done")
    return notes


def main(argv: list[str] | None = None) -> int:
    """`python -m coadapt_core.experiments.transfer ROBOT REFERENCE OTHER`: the backend
    check's tables for the registered robot on two registered simulators."""
    from coadapt_core.plugins import get_registry

    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 3:
        print(
            "usage: python -m coadapt_core.experiments.transfer "
            "ROBOT REFERENCE_SIMULATOR OTHER_SIMULATOR",
            file=sys.stderr,
        )
        return 2
    try:
        robot = get_registry().create("robot", args[0])
        figures = compare_backends(robot, reference=args[1], other=args[2])
    except CoadaptError as exc:  # an unknown robot or simulator: one line
        print(f"error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    print(markdown_tables(figures))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
