"""The files of an export (`coadapt export`: one CSV or Parquet file per table), found from
the folder or any one file in it, and read as (columns, rows) with an empty cell as
`MISSING`. Reading is data only: CSV text and Parquet columns, never unpickled or evaluated;
the importer (`coadapt_core.results.importer`) checks the values and merges them."""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path
from typing import Any

from coadapt_core.errors import UserError, did_you_mean
from coadapt_core.results.export import EXPORT_TABLES, FORMATS, OPTIONAL_TABLES

#: a CSV field may hold a whole run configuration or summary (Pareto fronts), larger than
#: csv's default limit
FIELD_LIMIT = 256 * 1024 * 1024


class _Missing:
    """An empty cell: the column does not apply to this row (another run's objective, a
    nullable value the export wrote as nothing)."""

    def __repr__(self) -> str:
        return "MISSING"


MISSING = _Missing()


def export_files(path: str | Path, fmt: str | None = None) -> tuple[dict[str, Path], str]:
    """The export's file per table and its format, from the folder `coadapt export -o` wrote
    or any one file in it (`runs.csv`, `evaluations.parquet`, ...)."""
    given = Path(path)
    if fmt is not None and fmt not in FORMATS:
        raise UserError(
            f"import format '{fmt}' is not one of {', '.join(FORMATS)}{did_you_mean(fmt, FORMATS)}",
            field="format",
        )
    if given.is_file():
        stem, _, suffix = given.name.partition(".")
        if stem not in EXPORT_TABLES or suffix not in FORMATS:
            raise UserError(
                f"'{given}' is not a file `coadapt export` writes; give its folder or one of "
                f"{', '.join(f'{t}.csv' for t in EXPORT_TABLES)} (or .parquet)",
                field="file",
            )
        if fmt is not None and fmt != suffix:
            raise UserError(f"'{given}' is a .{suffix} file but --format is {fmt}", field="format")
        folder, fmt = given.parent, suffix
    elif given.is_dir():
        folder = given
        if fmt is None:
            found = [f for f in FORMATS if (folder / f"runs.{f}").is_file()]
            if not found:
                raise UserError(
                    f"folder '{given}' holds no runs.csv or runs.parquet: not an export folder "
                    "(`coadapt export -o FOLDER` writes one)",
                    field="file",
                )
            if len(found) > 1:
                raise UserError(
                    f"folder '{given}' holds both runs.csv and runs.parquet; "
                    "choose one with --format",
                    field="format",
                )
            fmt = found[0]
    else:
        raise UserError(
            f"'{given}' does not exist; give the folder `coadapt export -o` wrote, or a file in it",
            field="file",
        )
    files = {t: folder / f"{t}.{fmt}" for t in EXPORT_TABLES}
    # an export from before a table existed: that table is empty
    files = {t: p for t, p in files.items() if t not in OPTIONAL_TABLES or p.is_file()}
    missing = [p.name for p in files.values() if not p.is_file()]
    if missing:
        raise UserError(
            f"export folder '{folder}' lacks {', '.join(missing)} (an export holds "
            f"{', '.join(f'{t}.{fmt}' for t in EXPORT_TABLES if t not in OPTIONAL_TABLES)})",
            field="file",
        )
    return files, fmt


def _read_csv(path: Path) -> tuple[list[str], list[dict[str, Any]]]:
    old = csv.field_size_limit()
    csv.field_size_limit(min(FIELD_LIMIT, sys.maxsize))
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            columns = list(reader.fieldnames or [])
            rows = []
            for r in reader:
                if None in r:  # more cells than the header names
                    raise UserError(
                        f"{path.name} line {reader.line_num}: "
                        "more values than the header has columns",
                        field="file",
                    )
                rows.append({k: MISSING if v in ("", None) else v for k, v in r.items()})
    except UnicodeDecodeError:
        raise UserError(
            f"{path.name} is not UTF-8 text: not a CSV file `coadapt export` wrote", field="file"
        ) from None
    except csv.Error as exc:
        raise UserError(f"{path.name} is not a readable CSV file: {exc}", field="file") from None
    finally:
        csv.field_size_limit(old)
    if len(set(columns)) != len(columns):
        raise UserError(f"{path.name}: the header names a column twice", field="file")
    return columns, rows


def _read_parquet(path: Path) -> tuple[list[str], list[dict[str, Any]]]:
    try:
        import pandas as pd
        import pyarrow  # noqa: F401
    except ImportError:
        raise UserError(
            "parquet import needs pandas and pyarrow: pip install 'coadapt[parquet]' "
            "(or export and import as csv)",
            field="format",
        ) from None
    try:
        frame = pd.read_parquet(path)
    except Exception as exc:  # not Parquet, damaged: whatever pyarrow says, in one line
        detail = " ".join(str(exc).split())[:160]
        raise UserError(
            f"{path.name} is not a readable Parquet file: {detail}", field="file"
        ) from None
    columns = [str(c) for c in frame.columns]
    rows = []
    for record in frame.to_dict(orient="records"):
        row = {}
        for k, v in record.items():
            if hasattr(v, "item"):  # numpy scalar -> Python
                v = v.item()
            # Parquet cannot tell a missing cell from NaN: both are read as missing
            row[str(k)] = MISSING if v is None or (isinstance(v, float) and math.isnan(v)) else v
        rows.append(row)
    return columns, rows


def read_table(path: Path, fmt: str) -> tuple[list[str], list[dict[str, Any]]]:
    """(columns, rows) of one exported file; an empty cell is `MISSING`."""
    return _read_csv(path) if fmt == "csv" else _read_parquet(path)
