"""What a grid cell run on another machine hands back: its run folder as bytes and its store
rows in `coadapt export`'s CSV form (plain data; no store object, no pickled value), and the
checked unpacking of both on the receiving side.

Nothing in a bundle is trusted as a path: a file's name must be a relative path without
`..`, and the receiver chooses the folder (`<out>/<run id>`, the run id checked); no link is
packed or written; sizes are capped. The rows go through `coadapt import`'s checks and merge
rule (`coadapt_core.results.importer`), with the run's folder recorded as the receiver's."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

from coadapt_core.errors import UserError
from coadapt_core.results.export import EXPORT_TABLES, export_tables
from coadapt_core.results.store import ResultsStore
from coadapt_core.validation import is_run_id

#: the evaluation buffer (`coadapt_core.coadapt.state.BUFFER_FILE_STEM`): a finished run has
#: none; a running cell's state sent back keeps it (a resume needs it)
BUFFER_GLOB = "buffer-*.npz"
STATE_NAME = "state.json"


@dataclass(frozen=True)
class Limits:
    """Caps on what a bundle may hold; more is refused in one line naming the cap."""

    files: int = 10_000
    file_bytes: int = 2 * 1024**3
    total_bytes: int = 8 * 1024**3
    table_bytes: int = 1024**3


LIMITS = Limits()


class BundleError(UserError):
    """A bundle that breaks a rule (a path leaving the folder, a link, a cap, a foreign run)."""


def pack_folder(
    run_dir: str | os.PathLike, *, keep_buffer: bool = False, limits: Limits = LIMITS
) -> dict[str, bytes]:
    """{relative POSIX path: bytes} of every regular file under `run_dir` (links and other
    non-files are left out; the evaluation buffer too unless `keep_buffer`)."""
    root = Path(run_dir)
    files: dict[str, bytes] = {}
    total = 0
    for path in sorted(root.rglob("*")):
        if path.is_symlink() or not path.is_file():
            continue
        rel = path.relative_to(root).as_posix()
        if not keep_buffer and PurePosixPath(rel).match(BUFFER_GLOB) and "/" not in rel:
            continue
        data = path.read_bytes()
        total += len(data)
        _check_size(rel, len(data), total, len(files) + 1, limits)
        files[rel] = data
    return files


def _check_size(rel: str, size: int, total: int, count: int, limits: Limits) -> None:
    if size > limits.file_bytes:
        raise BundleError(
            f"bundle file '{rel}' is {size} bytes, over the cap of {limits.file_bytes}",
            field="bundle",
        )
    if total > limits.total_bytes:
        raise BundleError(f"bundle is over {limits.total_bytes} bytes in all", field="bundle")
    if count > limits.files:
        raise BundleError(f"bundle holds more than {limits.files} files", field="bundle")


def safe_relpath(name: Any) -> PurePosixPath:
    """A bundle's file name as a relative path that stays inside its folder: text, not empty,
    not absolute, no `..`, `.` or empty part, no backslash or NUL."""
    if not isinstance(name, str) or not name or "\\" in name or "\0" in name:
        raise BundleError(
            f"bundle file name {str(name)[:80]!r} is not a relative path", field="bundle"
        )
    rel = PurePosixPath(name)
    if rel.is_absolute() or name.startswith("/"):
        raise BundleError(f"bundle file name '{name[:80]}' is absolute", field="bundle")
    if any(part in ("..", ".", "") for part in name.split("/")):
        raise BundleError(
            f"bundle file name '{name[:80]}' has a '..', '.' or empty part", field="bundle"
        )
    return rel


def write_folder(files: Any, dest: str | os.PathLike, *, limits: Limits = LIMITS) -> Path:
    """Write a packed folder as `dest` (replacing what was there), every name checked first;
    the files go to a fresh folder beside `dest` that then takes its place, so a bad bundle
    writes nothing and nothing is written through a link."""
    if not isinstance(files, dict):
        raise BundleError("bundle files are not a mapping of names to bytes", field="bundle")
    checked: list[tuple[PurePosixPath, bytes]] = []
    total = 0
    for name, data in files.items():
        rel = safe_relpath(name)
        if not isinstance(data, bytes | bytearray):
            raise BundleError(f"bundle file '{name[:80]}' is not bytes", field="bundle")
        total += len(data)
        _check_size(name, len(data), total, len(checked) + 1, limits)
        checked.append((rel, bytes(data)))
    dest = Path(dest)
    if dest.is_symlink():
        raise BundleError(
            f"'{dest}' is a link; a run folder is not written through one", field="bundle"
        )
    dest.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".incoming-{dest.name}-", dir=dest.parent))
    try:
        for rel, data in checked:
            target = staging.joinpath(*rel.parts)
            target.parent.mkdir(parents=True, exist_ok=True)
            with open(target, "xb") as fh:  # a name given twice (a/b and a/./b) fails here
                fh.write(data)
        if dest.exists():
            shutil.rmtree(dest)
        staging.rename(dest)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return dest


def export_rows(store: ResultsStore, run_ids: list[str]) -> dict[str, str]:
    """{table: CSV text} of these runs, as `coadapt export --format csv` writes them."""
    with tempfile.TemporaryDirectory(prefix="coadapt-rows-") as tmp:
        written = export_tables(store, tmp, fmt="csv", run_ids=run_ids)
        return {name: Path(path).read_text(encoding="utf-8") for name, path in written.items()}


def import_rows(
    store: ResultsStore,
    tables: Any,
    *,
    run_id: str,
    folder: Path,
    cell: str | None = None,
    limits: Limits = LIMITS,
) -> Any:
    """Merge a bundle's rows into `store` by `coadapt import`'s rule, with the run's folder
    recorded as `folder`. The rows must hold exactly the run `run_id` (and, with `cell`,
    that grid cell's run); anything else is refused before anything is written."""
    from coadapt_core.results.import_files import export_files, read_table
    from coadapt_core.results.importer import import_tables

    if not isinstance(tables, dict) or set(tables) != set(EXPORT_TABLES):
        raise BundleError(
            f"bundle rows are not the tables {', '.join(EXPORT_TABLES)}", field="bundle"
        )
    if not is_run_id(run_id):
        raise BundleError(f"bundle run id {str(run_id)[:80]!r} is not a run id", field="bundle")
    with tempfile.TemporaryDirectory(prefix="coadapt-rows-") as tmp:
        for name, text in tables.items():
            if not isinstance(text, str) or len(text) > limits.table_bytes:
                raise BundleError(
                    f"bundle table {name} is not CSV text within {limits.table_bytes} bytes",
                    field="bundle",
                )
            Path(tmp, f"{name}.csv").write_text(text, encoding="utf-8")
        files, _ = export_files(tmp, "csv")
        _, runs = read_table(files["runs"], "csv")
        ids = {str(r.get("id")) for r in runs}
        if ids != {run_id}:
            raise BundleError(
                f"bundle rows hold runs {sorted(ids)[:3]}, not just {run_id}", field="bundle"
            )
        if cell is not None and str(runs[0].get("cell")) != cell:
            raise BundleError(f"bundle run {run_id} is not a run of cell {cell}", field="bundle")
        return import_tables(store, tmp, fmt="csv", relocate={run_id: folder.resolve()})


def retarget_state(run_dir: str | os.PathLike, *, out: str, store: str) -> bool:
    """Make a run folder's state name the store and runs folder of the machine it now lies
    on (`config.store`, `config.out`), so `coadapt run --resume` there records where that
    machine's grid reads; only those two values of the JSON change. False when the folder
    holds no state."""
    from coadapt_core.io import write_atomic

    path = Path(run_dir) / STATE_NAME
    if not path.is_file() or path.is_symlink():
        return False
    data = json.loads(path.read_text(encoding="utf-8"))
    config = data.get("config") if isinstance(data, dict) else None
    if not isinstance(config, dict):
        return False
    config["store"], config["out"] = store, out
    write_atomic(path, json.dumps(data).encode())
    return True
