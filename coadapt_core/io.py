"""Writing files safely: one JSON sanitiser and one atomic write for every file coadapt
keeps (run configs and summaries, state files, checkpoints, the store's JSON columns).

An atomic write goes through a temporary file beside the target and a rename, so a kill or
a full disk leaves the previous file and no partial one; an OS error is one line naming the
file (`UserError`)."""

from __future__ import annotations

import contextlib
import dataclasses
import errno
import json
import math
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from coadapt_core.errors import UserError


def jsonable(value: Any, *, nan: Any = None) -> Any:
    """`value` as plain JSON data: mappings (keys as strings), lists and tuples, numpy arrays
    and scalars (anything with `tolist`), dataclasses and pydantic models as mappings, paths
    as strings; a float NaN becomes `nan` (None: JSON has no NaN; pass `nan=math.nan` to keep
    it). Anything else is kept."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        value = dataclasses.asdict(value)
    elif hasattr(value, "model_dump") and not isinstance(value, type):
        value = value.model_dump()
    if isinstance(value, Mapping):
        return {str(k): jsonable(v, nan=nan) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v, nan=nan) for v in value]
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if hasattr(value, "tolist") and not isinstance(value, str | bytes):
        return jsonable(value.tolist(), nan=nan)
    if isinstance(value, float) and math.isnan(value):
        return nan
    return value


def disk_error(path: Path, exc: OSError) -> UserError:
    """One line for an OS error writing `path`."""
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return UserError(
            f"disk full writing '{path}'; nothing partial was left, "
            "free space and run the command again",
            field="out",
        )
    if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        return UserError(
            f"cannot write '{path}' ({os.strerror(exc.errno)}); pick a writable --out folder",
            field="out",
        )
    return UserError(f"cannot write '{path}' ({exc.strerror or type(exc).__name__})", field="out")


def write_atomic(path: str | os.PathLike, data: bytes | Callable[[Path], None]) -> Path:
    """Write `data` (bytes, or a function that writes the file it is given, e.g. a
    `torch.save`) to `path` through a temporary file and a rename. On any error the
    temporary file is removed; an OS error is a one-line `UserError` naming the file."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    try:
        if callable(data):
            data(tmp)
        else:
            with open(tmp, "wb") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError):
            raise disk_error(path, exc) from None
        raise
    return path


def write_json_atomic(path: str | os.PathLike, data: Any, *, indent: int | None = 2) -> Path:
    """`data` (through `jsonable`) as JSON text, atomically."""
    return write_atomic(path, json.dumps(jsonable(data), indent=indent).encode("utf-8"))


def latest_checkpoint(folder: str | os.PathLike) -> Path | None:
    """The newest checkpoint a `coadapt train --out FOLDER` left: `model_final.pt` or the
    last `checkpoints/model_<iteration>.pt`, whichever was written last (an interrupted or
    stopped training has no model_final.pt). None when the folder holds neither."""
    folder = Path(folder)
    found = [
        p
        for p in (folder / "model_final.pt", *(folder / "checkpoints").glob("model_*.pt"))
        if p.is_file()
    ]

    def order(path: Path) -> tuple[float, int]:
        digits = "".join(ch for ch in path.stem if ch.isdigit())
        return (path.stat().st_mtime, int(digits) if digits else 1 << 62)

    return max(found, key=order) if found else None


def checkpoint_path(given: str | os.PathLike, *, field: str) -> Path:
    """A checkpoint option's value: a file as given, or a training folder's newest checkpoint
    (`latest_checkpoint`); a folder without one is a one-line `UserError`."""
    path = Path(given)
    if not path.is_dir():
        return path
    found = latest_checkpoint(path)
    if found is None:
        raise UserError(
            f"{field} {path} is a folder without model_final.pt or checkpoints/model_*.pt; give a "
            "checkpoint file or the --out folder of a `coadapt train`",
            field=field.lstrip("-"),
        )
    return found


__all__ = [
    "checkpoint_path",
    "disk_error",
    "jsonable",
    "latest_checkpoint",
    "write_atomic",
    "write_json_atomic",
]
