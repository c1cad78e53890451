"""One cell of an experiment grid: the run it stands for (method, objective, terrain, seed,
preset, simulator, optionally optimizer and robot), its stable key and its `coadapt run`
arguments. Planning (grid_plan.py) and the config hash (cell_hash.py) both build on it."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from coadapt_core.errors import UserError
from coadapt_core.options import STUDY_STORAGE_OPTION


@dataclass(frozen=True)
class Cell:
    """One run of the grid."""

    method: str
    objective: str
    terrain: str
    seed: int
    preset: str
    sim: str
    optimizer: str | None = (
        None  # None: the method's default (`coadapt_core.methods.optimizer_for`)
    )
    robot: str | None = (
        None  # None: `coadapt run`'s default robot (a cell made by a GridSpec always names it)
    )

    @property
    def key(self) -> str:
        """Stable text key; what the store's `runs.cell` and `grid_cells.cell` hold (the
        robot first, when the cell names one)."""
        parts = [f"robot={self.robot}"] if self.robot else []
        parts += [
            f"method={self.method}",
            f"objective={self.objective}",
            f"terrain={self.terrain}",
            f"seed={self.seed}",
            f"preset={self.preset}",
            f"sim={self.sim}",
        ]
        if self.optimizer:
            parts.append(f"optimizer={self.optimizer}")
        return "|".join(parts)

    @property
    def slug(self) -> str:
        return self.key.replace("|", "_").replace("=", "-").replace(",", "+")

    def run_args(
        self,
        *,
        out_dir: str | None = None,
        resume: str | None = None,
        extra: Sequence[str] = (),
        store: str | None = None,
    ) -> list[str]:
        """The `coadapt run` arguments of this cell. With `store`, the run records into it,
        and an optimizer that keeps a study (it declares the option
        `coadapt_core.options.STUDY_STORAGE_OPTION`) keeps it there too."""
        args = [
            "run",
            "--method", self.method,
            "--objective", self.objective,
            "--terrain", self.terrain,
            "--seed", str(self.seed),
            "--preset", self.preset,
            "--sim", self.sim,
        ]  # fmt: skip
        if self.robot:
            args += ["--robot", self.robot]
        if self.optimizer:
            args += ["--optimizer", self.optimizer]
        if out_dir:
            args += ["--out", out_dir]
        if store:
            args += ["--store", store]
            if keeps_study(self.method, self.optimizer):
                args += ["--optimizer-option", f"{STUDY_STORAGE_OPTION}={store}"]
        if resume:
            args += ["--resume", resume]
        return [*args, *extra, "--json"]


def keeps_study(method: str, optimizer: str | None) -> bool:
    """The optimizer a cell of `method` runs declares the option that keeps a study in a
    database (`STUDY_STORAGE_OPTION`); a cell without an optimizer runs the method's default one."""
    from coadapt_core.methods import optimizer_for
    from coadapt_core.plugins import get_registry

    try:
        cls = get_registry().get("optimizer", optimizer_for(method, optimizer or ""))
    except UserError:
        return False
    return any(spec.name == STUDY_STORAGE_OPTION for spec in getattr(cls, "option_specs", ()))
