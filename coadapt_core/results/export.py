"""Export the results store as flat tables (CSV always; Parquet through pandas + pyarrow
when installed): one file per table, JSON columns flattened into plain columns."""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from coadapt_core.errors import UserError, did_you_mean
from coadapt_core.results.schema import metadata
from coadapt_core.results.store import ResultsStore

FORMATS = ("csv", "parquet")
EXPORT_TABLES = ("runs", "evaluations", "training_phases", "checkpoints", "verifications")
#: tables an export may lack (written by a coadapt before they existed): read as empty
OPTIONAL_TABLES = ("verifications",)


def _flatten(name: str, row: dict[str, Any], design_names: dict[str, list[str]]) -> dict[str, Any]:
    """JSON columns become columns: design -> one per variable, costs -> cost_<objective>,
    surrogate_error -> surrogate_error_<objective>, summary/config stay JSON text."""
    out: dict[str, Any] = {}
    for key, value in row.items():
        if name == "evaluations" and key == "design":
            values = json.loads(value)
            names = design_names.get(row["run_id"]) or []
            for i, v in enumerate(values):
                out[names[i] if i < len(names) else f"x{i}"] = v
            out["design"] = value
        elif name == "evaluations" and key in ("costs", "surrogate_error"):
            prefix = "cost" if key == "costs" else "surrogate_error"
            for obj, v in (json.loads(value) if value else {}).items():
                out[f"{prefix}_{obj}"] = v
        elif name == "training_phases" and key == "extra":
            for k, v in (json.loads(value) if value else {}).items():
                out[f"extra_{k}"] = v
        else:
            out[key] = value
    return out


def space_of_run(run: dict[str, Any], dim: int | None = None) -> dict[str, Any] | None:
    """The run's design space as `DesignSpace.to_dict()` gives it: from its config (recorded
    since runs carry it), else its summary (the ranges it searched), else the robot plugin's
    space of the same dimension; None when nothing names it."""
    cfg = run.get("config") if isinstance(run.get("config"), dict) else {}
    summary = run.get("summary") if isinstance(run.get("summary"), dict) else {}
    spaces = summary.get("spaces") if isinstance(summary.get("spaces"), list) else []
    for space in (cfg.get("design_space"), summary.get("final_space"), *spaces[:1]):
        if isinstance(space, dict) and isinstance(space.get("variables"), list):
            return space
    robot = run.get("robot") or cfg.get("robot")
    if robot and dim is not None:
        try:
            from coadapt_core.plugins import get_registry

            robot_obj = get_registry().get("robot", str(robot))()
            for mixed in (False, True):
                space = robot_obj.design_space(mixed=mixed)
                if space.dim == dim:
                    return space.to_dict()
        except Exception:  # an uninstalled robot plugin: no names
            return None
    return None


def design_names_of(run: dict[str, Any], dim: int | None = None) -> list[str] | None:
    """Variable names of the run's design space (see `space_of_run`)."""
    cfg = run.get("config") if isinstance(run.get("config"), dict) else {}
    if isinstance(cfg.get("design_names"), list):
        return [str(n) for n in cfg["design_names"]]
    space = space_of_run(run, dim)
    return None if space is None else [str(v["name"]) for v in space["variables"]]


def _design_names(store: ResultsStore, run_ids: Sequence[str] | None) -> dict[str, list[str]]:
    """Variable names per run, from its design space (see `space_of_run`)."""
    names: dict[str, list[str]] = {}
    for run in store.list_runs(run_ids=run_ids):
        dim = None
        first = store.evaluations(run["id"])[:1]
        if first:
            dim = len(first[0].design)
        found = design_names_of(run, dim)
        if found:
            names[run["id"]] = found
    return names


def export_tables(
    store: ResultsStore,
    out_dir: str | os.PathLike,
    *,
    fmt: str = "csv",
    run_ids: Sequence[str] | None = None,
) -> dict[str, Path]:
    """Write runs, evaluations, training_phases, checkpoints and verifications to `out_dir`;
    returns the files by table."""
    if fmt not in FORMATS:
        raise UserError(
            f"export format '{fmt}' is not one of {', '.join(FORMATS)}{did_you_mean(fmt, FORMATS)}",
            field="format",
        )
    if run_ids is not None:
        missing = [r for r in run_ids if not store.has_run(r)]
        if missing:
            raise UserError(f"run '{missing[0]}' is not in store {store.url}", field="run")
    if fmt == "parquet":
        try:
            import pandas as pd
            import pyarrow  # noqa: F401
        except ImportError:
            raise UserError(
                "parquet export needs pandas and pyarrow: pip install 'coadapt[parquet]' "
                "(or use --format csv)",
                field="format",
            ) from None
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    names = _design_names(store, run_ids)
    written: dict[str, Path] = {}
    for table in EXPORT_TABLES:
        rows = [_flatten(table, r, names) for r in store.table_rows(table, run_ids)]
        columns: list[str] = []
        for r in rows:
            columns.extend(k for k in r if k not in columns)
        if not columns:  # an empty table still gets its header
            columns = [c.name for c in metadata.tables[table].columns]
        path = out / f"{table}.{fmt}"
        if fmt == "csv":
            with path.open("w", newline="") as fh:
                writer = csv.DictWriter(fh, fieldnames=columns)
                writer.writeheader()
                for r in rows:
                    writer.writerow(r)
        else:
            import pandas as pd

            pd.DataFrame(rows, columns=columns or None).to_parquet(path, index=False)
        written[table] = path
    return written
