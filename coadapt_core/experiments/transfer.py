"""Sim-to-sim check: do two simulator backends move the same robot the same way?

The same open-loop joint-target sequence from the same initial state, randomization off,
on two backends (MuJoCo and PyBullet by default), for a few designs; the first second is
compared:

1. swing — base welded in the air (`fixed_base=True`), sinusoidal targets on every
   actuated joint: joint position, velocity and torque trajectories (no contact, so this
   isolates masses, inertias, frames, armature, damping, actuation and integration);
2. standing — on flat ground holding the default pose: base height, base orientation and
   joint positions (adds the contact models).

`python -m coadapt_core.experiments.transfer` prints the figures as the Markdown tables of
docs/sim-to-sim.md.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

import numpy as np

from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.physics.simulator import Simulator
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


def _make(sim_cls: type[Simulator], robot: Robot, designs: np.ndarray, *, fixed_base: bool, **kwargs) -> Simulator:
    return sim_cls(
        robot, designs, terrain="flat", randomization=RandomizationConfig.off(), seed=0,
        fixed_base=fixed_base, **kwargs,
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
    reference: str | type[Simulator] = "mujoco",
    other: str | type[Simulator] = "pybullet",
    duration: float = 1.0,
    physics_dt: float = 0.005,
    decimation: int = 4,
    other_kwargs: dict | None = None,
) -> list[DesignFigures]:
    """Swing and standing figures per design (`DEFAULT_DESIGNS` when None), `other`
    measured against `reference`. Each backend simulates all designs as one batch."""
    designs = np.atleast_2d(np.asarray(DEFAULT_DESIGNS if designs is None else designs, dtype=float))
    ref_cls, other_cls = _resolve(reference), _resolve(other)
    steps = round(duration / (physics_dt * decimation))
    runs: dict[str, dict[str, dict[str, np.ndarray]]] = {"swing": {}, "standing": {}}
    for label, cls, extra in (("reference", ref_cls, {}), ("other", other_cls, other_kwargs or {})):
        common = {"physics_dt": physics_dt, "decimation": decimation, **extra}
        with _make(cls, robot, designs, fixed_base=True, **common) as sim:
            targets = swing_targets(sim.default_joint_pos.double().cpu().numpy(), steps, sim.control_dt)
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
        fig.standing["base_height"] = ErrorFigure.of(st_other["base_pos"][:, i, 2], st_ref["base_pos"][:, i, 2])
        angle = _orientation_error(st_other["base_quat"][:, i], st_ref["base_quat"][:, i])
        fig.standing["orientation"] = ErrorFigure.of(angle, np.zeros_like(angle))
        fig.standing["joint_pos"] = ErrorFigure.of(st_other["joint_pos"][:, i], st_ref["joint_pos"][:, i])
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
        units = {"joint_pos": "rad", "joint_vel": "rad/s", "joint_torque": "N m", "base_height": "m", "orientation": "rad"}
        for test, table in (("swing", fig.swing), ("standing", fig.standing)):
            for key, err in table.items():
                lines.append(f"| {test} | {key} ({units[key]}) | {err.rms:.4f} | {err.max:.4f} |")
        lines.append("")
        lines.append(
            f"Swing joint motion RMS {fig.swing_amplitude:.3f} rad; standing base height drop over 1 s: "
            f"reference {fig.height_drop['reference'] * 100:.2f} cm, other {fig.height_drop['other'] * 100:.2f} cm."
        )
        lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from coadapt_core.plugins import get_registry

    robot = get_registry().create("robot", "kuafu")
    print(markdown_tables(compare_backends(robot)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
