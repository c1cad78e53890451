"""The paper's own figures, shipped as data: Tables 6, 7 and 9 of Du et al. 2025 ("Efficient
co-adaptation of humanoid robot design and locomotion control using surrogate-guided
optimization", Biomimetic Intelligence and Robotics, doi:10.1016/j.birob.2025.100255),
transcribed into `paper_du2025.json` beside this module (percentages, millions and hours as
printed). `coadapt report` sets them beside the measured figures
(`coadapt_core.analysis.paper_comparison`); tests/core/test_paper_data.py checks every
number against the paper's text.

Names in the data are the registry's: methods as `coadapt run --method` takes them,
objectives as `--objective`, terrains as `--terrain`, design variables as the paper robot's
design space names them (`design_variables` maps the paper's column to it)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from typing import Any

DATA_FILE = "paper_du2025.json"


@dataclass(frozen=True)
class PaperTables:
    """The paper's tables, with percentages as fractions (`improvement` 0.058 for 5.8 %)."""

    citation: str
    notes: tuple[str, ...]
    #: paper column -> design variable name (thigh -> the space's thigh variable, ...)
    design_variables: dict[str, str]
    #: the paper's own method, the one the others are measured against (Table 7 ratios)
    reference_method: str
    #: (objective, method, terrain) -> {thigh, shank, improvement, sim2sim_improvement}
    table6: dict[tuple[str, str, str], dict[str, float]]
    #: method -> {interactions_training, interactions_evaluation, interactions_total (counts),
    #: hours_training, hours_evaluation, hours_total}
    table7: dict[str, dict[str, float]]
    #: (objective, method, terrain) -> {thigh, hip_motor, shank, knee_motor, improvement}
    table9: dict[tuple[str, str, str], dict[str, float]]

    @property
    def methods(self) -> list[str]:
        """The paper's methods in its tables' order."""
        return list(self.table7)


def _fraction(row: dict[str, Any], name: str) -> float:
    return float(row[f"{name}_pct"]) / 100.0


@lru_cache(maxsize=1)
def paper_tables() -> PaperTables:
    """The shipped data, parsed once."""
    data = json.loads(resources.files(__package__).joinpath(DATA_FILE).read_text(encoding="utf-8"))
    t6 = {
        (r["objective"], r["method"], r["terrain"]): {
            "thigh": float(r["thigh"]),
            "shank": float(r["shank"]),
            "improvement": _fraction(r, "improvement"),
            "sim2sim_improvement": _fraction(r, "sim2sim_improvement"),
        }
        for r in data["table6"]["rows"]
    }
    t7 = {
        r["method"]: {
            "interactions_training": 1e6 * float(r["interactions_training_million"]),
            "interactions_evaluation": 1e6 * float(r["interactions_evaluation_million"]),
            "interactions_total": 1e6 * float(r["interactions_total_million"]),
            "hours_training": float(r["hours_training"]),
            "hours_evaluation": float(r["hours_evaluation"]),
            "hours_total": float(r["hours_total"]),
        }
        for r in data["table7"]["rows"]
    }
    t9 = {
        (r["objective"], r["method"], r["terrain"]): {
            "thigh": float(r["thigh"]),
            "hip_motor": float(r["hip_motor"]),
            "shank": float(r["shank"]),
            "knee_motor": float(r["knee_motor"]),
            "improvement": _fraction(r, "improvement"),
        }
        for r in data["table9"]["rows"]
    }
    return PaperTables(
        citation=data["citation"],
        notes=tuple(data["notes"]),
        design_variables=dict(data["design_variables"]),
        reference_method=data["table7"]["rows"][0]["method"],
        table6=t6,
        table7=t7,
        table9=t9,
    )
