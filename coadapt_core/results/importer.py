"""Load an export (`coadapt export`: one CSV or Parquet file per table) back into a results
store, merging it with what the store already holds.

Merge rule, per run id: a run the store does not hold is added with all its rows, as the
export recorded them (status, times, code version, configuration and summary unchanged). A
run the store already holds is replaced, with all its rows, only when the imported copy is
further along: finished where the store's copy is not, or of the same finish state and
updated later. Otherwise the store's copy is kept and the imported one skipped. Importing the
same export twice therefore changes nothing the second time, and two stores exported and
imported into a third hold each run once.

Everything in the files is data: values are parsed as numbers or JSON text, checked against
the store's columns, and written in one transaction (a bad file writes nothing). No value is
unpickled, evaluated, or opened as a path (`runs.run_dir` and `checkpoints.path` are stored as
text, as the export held them)."""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

import sqlalchemy as sa

from coadapt_core.errors import UserError
from coadapt_core.results.export import EXPORT_TABLES
from coadapt_core.results.import_files import MISSING, export_files, read_table
from coadapt_core.results.schema import EVALUATION_KINDS, metadata
from coadapt_core.results.storage import StoreError
from coadapt_core.results.store import ResultsStore
from coadapt_core.validation import is_run_id

#: the unique key of a child table's row (the store's own unique constraints)
ROW_KEYS = {
    "evaluations": ("run_id", "outer", "inner", "kind", "idx"),
    "training_phases": ("run_id", "outer", "idx"),
    "checkpoints": ("run_id", "outer", "path"),
    "verifications": ("run_id", "key", "role"),
}
#: JSON text columns of the runs table and the type their value must have (None allowed)
RUN_JSON = {"config": dict, "summary": dict}


@dataclass
class ImportResult:
    """What an import did: run ids added, replaced (the import was further along) and
    skipped (the store's copy kept), and rows written per table."""

    source: Path
    fmt: str
    added: list[str] = field(default_factory=list)
    replaced: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    rows: dict[str, int] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {
            "source": str(self.source),
            "format": self.fmt,
            "added": self.added,
            "replaced": self.replaced,
            "skipped": self.skipped,
            "rows": self.rows,
        }


# -- values -------------------------------------------------------------------------------------
def _where(table: str, line: int, column: str) -> str:
    return f"{table} row {line}, column '{column}'"


def _number(value: Any, kind: type, where: str) -> int | float:
    if isinstance(value, bool):
        raise UserError(f"{where}: expected a number, got {value!r}", field="file")
    try:
        if kind is int:
            if isinstance(value, float):
                if not value.is_integer():
                    raise ValueError
                return int(value)
            return int(str(value).strip())
        return float(value)
    except (TypeError, ValueError, OverflowError):
        name = "an integer" if kind is int else "a number"
        raise UserError(
            f"{where}: expected {name}, got {str(value)[:40]!r}", field="file"
        ) from None


def _column_value(column: sa.Column, value: Any, where: str) -> Any:
    """A cell as the store's column holds it: int, float or text; `MISSING` -> None."""
    if value is MISSING:
        if not column.nullable and not column.primary_key:
            raise UserError(f"{where}: a value is required", field="file")
        return None
    if isinstance(column.type, sa.Integer):
        return _number(value, int, where)
    if isinstance(column.type, sa.Float):
        return _number(value, float, where)
    text = value if isinstance(value, str) else str(value)
    length = getattr(column.type, "length", None)
    if length is not None and len(text) > length:
        raise UserError(f"{where}: longer than {length} characters", field="file")
    return text


def _json_text(value: Any, kind: type, where: str) -> str | None:
    """JSON text of a runs column, checked to parse as `kind` (or null)."""
    if value is None:
        return None
    try:
        parsed = json.loads(value)
    except (TypeError, ValueError):
        raise UserError(f"{where}: not JSON text", field="file") from None
    if parsed is not None and not isinstance(parsed, kind):
        raise UserError(
            f"{where}: expected a JSON {kind.__name__}, got {type(parsed).__name__}", field="file"
        )
    return value


def _scalar(value: Any) -> Any:
    """A flattened JSON value back to JSON: numbers, true/false, null and JSON text parse,
    anything else stays the text it is (a Python `True` the CSV writer wrote is a bool)."""
    if not isinstance(value, str):
        return value
    if value in ("True", "False"):
        return value == "True"
    try:
        return json.loads(value)
    except ValueError:
        return value


# -- rows -------------------------------------------------------------------------------------
def _run_rows(columns: list[str], rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    table = metadata.tables["runs"]
    if "id" not in columns or "status" not in columns:
        raise UserError(
            "runs file: the header lacks 'id' or 'status' "
            "(not a runs table `coadapt export` wrote)",
            field="file",
        )
    out: dict[str, dict[str, Any]] = {}
    for line, raw in enumerate(rows, start=2):
        row = {}
        for column in table.columns:
            if column.name in raw:
                row[column.name] = _column_value(
                    column, raw[column.name], _where("runs", line, column.name)
                )
        if not is_run_id(row.get("id")):
            raise UserError(
                f"runs row {line}: {row.get('id')!r} is not a run id "
                "(letters, digits and . _ + = - only)",
                field="file",
            )
        for name, kind in RUN_JSON.items():
            if name in row:
                row[name] = _json_text(row[name], kind, _where("runs", line, name))
        for name in ("created_at", "updated_at"):
            if row.get(name) is None:
                raise UserError(f"{_where('runs', line, name)}: a value is required", field="file")
        out[row["id"]] = row  # a run listed twice: the last row
    return out


def _child_rows(
    name: str, columns: list[str], rows: list[dict[str, Any]], run_ids: set[str]
) -> dict[tuple, dict[str, Any]]:
    """Rows of evaluations, training_phases or checkpoints, keyed by their unique key, with
    the flattened JSON columns folded back (design, costs, surrogate_error, extra)."""
    table = metadata.tables[name]
    plain = [
        c
        for c in table.columns
        if c.name != "id" and c.name not in ("costs", "surrogate_error", "extra")
    ]
    needed = [k for k in ROW_KEYS[name] if k not in columns]
    if needed:
        raise UserError(
            f"{name} file: the header lacks {', '.join(needed)} "
            "(not a table `coadapt export` wrote)",
            field="file",
        )
    out: dict[tuple, dict[str, Any]] = {}
    for line, raw in enumerate(rows, start=2):
        row = {
            c.name: _column_value(c, raw.get(c.name, MISSING), _where(name, line, c.name))
            for c in plain
        }
        if row["run_id"] not in run_ids:
            raise UserError(
                f"{name} row {line}: run {row['run_id']!r} is not in the runs file", field="file"
            )
        if name == "evaluations":
            where = _where(name, line, "design")
            try:
                design = json.loads(row["design"])
            except ValueError:
                raise UserError(f"{where}: not JSON text", field="file") from None
            if not isinstance(design, list) or not all(
                isinstance(x, int | float) and not isinstance(x, bool) for x in design
            ):
                raise UserError(f"{where}: expected a JSON list of numbers", field="file")
            if row["kind"] not in EVALUATION_KINDS:
                raise UserError(
                    f"{_where(name, line, 'kind')}: '{row['kind']}' is not one of "
                    f"{', '.join(EVALUATION_KINDS)}",
                    field="file",
                )
            costs = {
                k[len("cost_") :]: _number(v, float, _where(name, line, k))
                for k, v in raw.items()
                if k.startswith("cost_") and v is not MISSING
            }
            errors = {
                k[len("surrogate_error_") :]: _number(v, float, _where(name, line, k))
                for k, v in raw.items()
                if k.startswith("surrogate_error_") and v is not MISSING
            }
            row["costs"] = json.dumps(costs, sort_keys=True)
            row["surrogate_error"] = json.dumps(errors, sort_keys=True) if errors else None
        elif name == "training_phases":
            extra = {
                k[len("extra_") :]: _scalar(v)
                for k, v in raw.items()
                if k.startswith("extra_") and v is not MISSING
            }
            row["extra"] = json.dumps(extra, sort_keys=True)
        out[tuple(row[k] for k in ROW_KEYS[name])] = row
    return out


def _rank(run: dict[str, Any]) -> tuple[bool, float]:
    """How far along a copy of a run is: finished first, then the later update."""
    return run.get("status") == "finished", float(run.get("updated_at") or 0.0)


def _chunks(rows: list[dict[str, Any]], size: int = 500) -> Iterator[list[dict[str, Any]]]:
    for i in range(0, len(rows), size):
        yield rows[i : i + size]


def _relocate(
    runs: dict[str, dict[str, Any]],
    checkpoints: dict[tuple, dict[str, Any]],
    relocate: Mapping[str, Path],
) -> None:
    """Point the named runs at the folders the importer chose (`{run id: folder}`): `run_dir`
    becomes the folder, and a checkpoint path inside the old `run_dir` the same file inside
    the new one. The old values are only compared as text, never opened; a checkpoint path
    that was not inside the old folder stays the text it was (no path will resolve it)."""
    for run_id, folder in relocate.items():
        run = runs.get(run_id)
        if run is None:
            continue
        old = PurePosixPath(str(run.get("run_dir") or "/nonexistent"))
        run["run_dir"] = str(folder)
        for row in checkpoints.values():
            if row["run_id"] != run_id or not isinstance(row.get("path"), str):
                continue
            try:
                rel = PurePosixPath(row["path"]).relative_to(old)
            except ValueError:
                continue
            if rel.parts and ".." not in rel.parts:
                row["path"] = str(Path(folder, *rel.parts))


def import_tables(
    store: ResultsStore,
    path: str | Path,
    *,
    fmt: str | None = None,
    relocate: Mapping[str, Path] | None = None,
) -> ImportResult:
    """Read the export at `path` (its folder or a file in it), check every row, and merge it
    into `store` in one transaction (see the module's merge rule). `relocate` ({run id:
    folder}) records those runs' folders where the caller put them (`_relocate`): a grid's
    Ray cell hands back rows that name a scratch folder on another machine."""
    files, fmt = export_files(path, fmt)
    columns, raw = read_table(files["runs"], fmt)
    runs = _run_rows(columns, raw)
    children = {}
    for name in EXPORT_TABLES:
        if name != "runs" and name in files:
            columns, raw = read_table(files[name], fmt)
            children[name] = _child_rows(name, columns, raw, set(runs))
    if relocate:
        _relocate(runs, children["checkpoints"], relocate)
    result = ImportResult(source=Path(path), fmt=fmt, rows={t: 0 for t in EXPORT_TABLES})
    try:
        _merge(store, runs, children, result)
    except (
        sa.exc.SQLAlchemyError
    ) as exc:  # a row the database refuses, a store that cannot be written
        raise StoreError(store.url, exc) from None
    return result


def _merge(
    store: ResultsStore,
    runs: dict[str, dict[str, Any]],
    children: dict[str, dict[tuple, dict[str, Any]]],
    result: ImportResult,
) -> None:
    runs_table = metadata.tables["runs"]
    with store.engine.begin() as conn:
        existing = {}
        ids = list(runs)
        for i in range(0, len(ids), 500):
            query = sa.select(runs_table.c.id, runs_table.c.status, runs_table.c.updated_at).where(
                runs_table.c.id.in_(ids[i : i + 500])
            )
            existing.update({r["id"]: dict(r) for r in conn.execute(query).mappings()})
        take = []
        for run_id, run in runs.items():
            if run_id not in existing:
                result.added.append(run_id)
            elif _rank(run) > _rank(existing[run_id]):
                result.replaced.append(run_id)
            else:
                result.skipped.append(run_id)
                continue
            take.append(run_id)
        for run_id in result.replaced:  # the store's copy and all its rows give way
            for name in EXPORT_TABLES[1:]:
                table = metadata.tables[name]
                conn.execute(table.delete().where(table.c.run_id == run_id))
            conn.execute(runs_table.delete().where(runs_table.c.id == run_id))
        chosen = set(take)
        new_runs = [runs[r] for r in take]
        for chunk in _chunks(new_runs):
            conn.execute(runs_table.insert(), chunk)
        result.rows["runs"] = len(new_runs)
        for name, rows in children.items():
            kept = [r for r in rows.values() if r["run_id"] in chosen]
            for chunk in _chunks(kept):
                conn.execute(metadata.tables[name].insert(), chunk)
            result.rows[name] = len(kept)
