"""Checks for values that arrive from outside: command lines, config files, shared stores.

A value read from a results store or a run folder is data someone else wrote; it is never
trusted as a path. Run ids are checked against `RUN_ID_PATTERN`, and a path taken from a store
or a state file is accepted only when it resolves inside the folder it belongs to. Every
failure is a one-line `UserError` naming the field and what is accepted.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

from coadapt_core.errors import UserError

#: what a run id may look like: letters, digits and . _ + - (no separators, no '..')
RUN_ID_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+=-]{0,199}$")


def is_run_id(value: object) -> bool:
    return isinstance(value, str) and bool(RUN_ID_PATTERN.match(value)) and ".." not in value


def check_run_id(value: object, *, field: str = "run_id") -> str:
    """`value` if it is a well-formed run id, else a one-line `UserError`."""
    if not is_run_id(value):
        raise UserError(
            f"{field} {value!r} is not a run id "
            "(letters, digits and . _ + = - only, no '..' or '/')",
            field=field,
        )
    return str(value)


def inside(base: str | os.PathLike, path: str | os.PathLike, *, field: str = "path") -> Path:
    """`path` (relative to `base`, or absolute) resolved, if it lies inside `base`; otherwise
    a one-line `UserError`. Symbolic links are followed before the check."""
    root = Path(base).resolve()
    target = (root / Path(path)).resolve()
    if target != root and root not in target.parents:
        raise UserError(f"{field} '{path}' lies outside '{root}'; refused", field=field)
    return target


def run_folder(out: str | os.PathLike, run_id: object, *, field: str = "run_id") -> Path:
    """The folder of run `run_id` inside `out` (the run id checked, the result inside `out`)."""
    return inside(out, check_run_id(run_id, field=field), field=field)


def finite_number(
    value: float, *, field: str, minimum: float | None = None, allow_equal: bool = True
) -> float:
    """`value` as a finite float (>= or > `minimum`), else a one-line `UserError`."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise UserError(
            f"--{field.replace('_', '-')} must be a number, got {value!r}", field=field
        ) from None
    if not math.isfinite(number) or (
        minimum is not None and (number < minimum or (number == minimum and not allow_equal))
    ):
        bound = "" if minimum is None else f" {'>=' if allow_equal else '>'} {minimum:g}"
        raise UserError(
            f"--{field.replace('_', '-')} must be a finite number{bound}, got {value!r}",
            field=field,
        )
    return number
