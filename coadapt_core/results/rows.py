"""What a store row holds, decoded: JSON columns in and out, a stored evaluation, a run's
best design, the run id scheme, and the paths a row names checked against its run folder
(store values are data anyone sharing the store may have written, never trusted as paths)."""

from __future__ import annotations

import json
import math
import time
import uuid
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from coadapt_core.errors import UserError
from coadapt_core.io import jsonable


def dumps(value: Any) -> str:
    # numpy scalars and arrays, paths and dataclass configs end up in run configs;
    # NaN costs stay NaN
    return json.dumps(jsonable(value, nan=math.nan), default=str, sort_keys=True)


def loads(text: str | None) -> Any:
    return None if text is None else json.loads(text)


def objective_list(config: dict[str, Any]) -> list[str]:
    value = config.get("objectives", config.get("objective"))
    if value is None:
        return []
    if isinstance(value, str):
        return [v.strip() for v in value.split(",") if v.strip()]
    return [str(v) for v in value]


@dataclass
class Evaluation:
    """One stored evaluated design."""

    run_id: str
    outer: int
    inner: int
    idx: int
    kind: str
    design: list[float]
    costs: dict[str, float]
    surrogate_error: dict[str, float] | None
    interactions: int
    seconds: float
    simulator: str | None
    created_at: float


def run_folder_of(run: dict[str, Any]) -> Path | None:
    """The run folder a store row names, or None when the row cannot be trusted with a path:
    its id must be a well-formed run id and its `run_dir` a folder named after that id (every
    run folder coadapt makes is `<out>/<run id>`). Store rows are data anyone sharing the
    store may have written; they never steer a path anywhere else."""
    from coadapt_core.validation import is_run_id

    run_id, run_dir = run.get("id"), run.get("run_dir")
    if not is_run_id(run_id) or not isinstance(run_dir, str) or not run_dir:
        return None
    folder = Path(run_dir).resolve()
    return folder if folder.name == run_id else None


def checkpoint_of(run: dict[str, Any], path: str | None) -> Path | None:
    """A checkpoint path from a store row (`checkpoints.path`, a summary's `checkpoint`),
    resolved inside the run's own folder (`run_folder_of`); None when it lies elsewhere."""
    from coadapt_core.validation import inside

    folder = run_folder_of(run)
    if folder is None or not path:
        return None
    try:
        return inside(folder, str(path))
    except UserError:
        return None


def best_of(run: dict[str, Any], real: Sequence[Evaluation]) -> tuple[list[float] | None, Any]:
    """(best design, its cost) of a run: what its summary recorded, else its real evaluation
    with the lowest cost of the first objective; (None, None) when it has neither."""
    summary = run.get("summary") or {}
    design, cost = summary.get("best_design"), summary.get("best_cost")
    first = run["objectives"][0] if run.get("objectives") else None
    if (design is None or cost is None) and real and first:
        best = min(real, key=lambda e: e.costs.get(first, float("inf")))
        design, cost = best.design, best.costs.get(first)
    return design, cost


def run_dict(row: Any) -> dict[str, Any]:
    d = dict(row)
    d["config"] = loads(d["config"]) or {}
    d["summary"] = loads(d["summary"])
    d["objectives"] = [o for o in (d["objectives"] or "").split(",") if o]
    return d


def new_run_id(
    method: str, objectives: Sequence[str], seed: Any = None, optimizer: str | None = None
) -> str:
    """The one run-id scheme, for run folders and store rows alike:
    `<UTC yyyymmdd-hhmmss>-<method>[-<optimizer>]-<objectives joined by +>[-s<seed>]-<6 hex>`
    (time first, so ids sort by start; random last, so two processes never share one)."""
    parts = [time.strftime("%Y%m%d-%H%M%S", time.gmtime()), str(method)]
    if optimizer:
        parts.append(str(optimizer))
    parts.append("+".join(objectives) or "run")
    if seed is not None:
        parts.append(f"s{seed}")
    return "-".join([*parts, uuid.uuid4().hex[:6]])
