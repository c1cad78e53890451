"""The files of run folders the dashboard may serve, and nothing else. A run folder is one the
store names for a well-formed run id (`coadapt_core.results.rows.run_folder_of`: a folder
named after the run), or the folder of that id under `--runs`; a file is served only when
its resolved path (links followed) lies inside that folder, is a plain file and has a type
listed in `SERVED`. No path from a URL or a store value is used before that check."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from coadapt_core.errors import UserError
from coadapt_core.results.rows import run_folder_of
from coadapt_core.validation import inside, is_run_id

#: file types served from a run folder, with their content type
SERVED = {
    ".gif": "image/gif",
    ".png": "image/png",
    ".json": "application/json",
    ".jsonl": "text/plain; charset=utf-8",
    ".yaml": "text/plain; charset=utf-8",
    ".md": "text/plain; charset=utf-8",
    ".csv": "text/plain; charset=utf-8",
    ".txt": "text/plain; charset=utf-8",
}
#: files a run's page lists when its folder holds them (the loop writes these)
LISTED = (
    "best_vs_nominal.gif",
    "convergence.png",
    "pareto.png",
    "summary.json",
    "config.yaml",
    "evaluations.jsonl",
    "trainings.jsonl",
)


class Refused(Exception):
    """A file the dashboard will not serve; the message says why, in one line."""


class RunFolders:
    """Where run folders are: the store's `run_dir` of each run, or `<runs>/<run id>`."""

    def __init__(self, runs: str | os.PathLike | None = None):
        self.runs = None if runs is None else Path(runs).resolve()

    def folder_of(self, run: dict[str, Any]) -> Path | None:
        """The run's folder when it exists: under `--runs` first, else the store's."""
        if not is_run_id(run.get("id")):
            return None
        if self.runs is not None:
            try:
                candidate = inside(self.runs, run["id"])
            except UserError:
                candidate = None
            if candidate is not None and candidate.is_dir():
                return candidate
        folder = run_folder_of(run)
        return folder if folder is not None and folder.is_dir() else None

    def state(self, run: dict[str, Any]) -> str:
        """'' when the run's folder is there; else one line saying why its files are not."""
        if self.folder_of(run) is not None:
            return ""
        if not run.get("run_dir"):
            return "the store names no run folder for this run"
        return (
            "the run folder the store names is not on this machine (deleted or moved); "
            "start the dashboard with --runs DIR to look for it by run id"
        )

    def listing(self, run: dict[str, Any]) -> list[str]:
        """The files of `LISTED` the run's folder holds."""
        folder = self.folder_of(run)
        if folder is None:
            return []
        return [name for name in LISTED if (folder / name).is_file()]

    def file(self, run: dict[str, Any], relative: str) -> tuple[Path, str]:
        """(path, content type) of a file inside the run's folder; `Refused` otherwise."""
        folder = self.folder_of(run)
        if folder is None:
            raise Refused(f"run {run.get('id')}: {self.state(run)}")
        if not relative or relative.startswith(("/", "\\")) or "\x00" in relative:
            raise Refused(
                "an absolute path is refused: only paths inside the run folder are served"
            )
        parts = relative.replace("\\", "/").split("/")
        if any(p in ("", ".", "..") for p in parts):
            raise Refused("a path with '.', '..' or empty parts is refused")
        try:
            path = inside(folder, relative)
        except UserError:
            raise Refused("the path leads outside the run folder; refused") from None
        kind = SERVED.get(path.suffix.lower())
        if kind is None:
            raise Refused(f"files of type '{path.suffix or 'none'}' are not served")
        if not path.is_file():
            raise Refused("no such file in the run folder")
        return path, kind
