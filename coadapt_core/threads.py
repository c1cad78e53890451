"""The thread budget: how many CPU threads this process may use (its affinity mask and its
cgroup's CPU quota), and one number given to torch and the physics alike (`--threads`).

Nothing here imports torch or pydantic at module level: `coadapt_core.launch` reads
`usable_cpus` before torch is loaded (libgomp reads its settings once), and the simulator
plugins import this module when they are listed. The `--threads` option is declared with
the other common options (`coadapt_core.cli.common_options.CommonOptions`). A run's budget is
never taken from a checkpoint: it is the machine's (or `--threads`), recorded in the run's
config.yaml.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

from coadapt_core.errors import UserError

#: a folder standing in for /sys/fs/cgroup (tests; a container that mounts it elsewhere)
ENV_CGROUP_ROOT = "COADAPT_CGROUP_ROOT"
CGROUP_ROOT = "/sys/fs/cgroup"

#: the budget `apply_threads` set in this process (None: `usable_cpus()`)
_budget: int | None = None


def _own_cgroups(proc_file: str = "/proc/self/cgroup") -> list[tuple[str, str]]:
    """(controllers, path) of each line of /proc/self/cgroup ('' controllers: cgroup v2)."""
    try:
        text = Path(proc_file).read_text()
    except OSError:
        return [("", "/")]
    out = []
    for line in text.splitlines():
        parts = line.split(":", 2)
        if len(parts) == 3:
            out.append((parts[1], parts[2] or "/"))
    return out or [("", "/")]


def _folders(base: Path, path: str) -> list[Path]:
    """`base`/`path` and every folder above it up to `base` (a limit set on a parent
    cgroup holds for its children; a path the container does not show is skipped)."""
    parts = [p for p in path.split("/") if p]
    return [base.joinpath(*parts[:i]) for i in range(len(parts), -1, -1)]


def _read_limit(quota_file: Path, period_file: Path | None = None) -> float | None:
    """CPUs a quota file allows: v2 `cpu.max` ("max 100000" or "150000 100000"), v1
    `cpu.cfs_quota_us` over `cpu.cfs_period_us` (-1: none); None without a limit."""
    try:
        if period_file is None:
            quota, _, period = quota_file.read_text().strip().partition(" ")
        else:
            quota, period = quota_file.read_text().strip(), period_file.read_text().strip()
        if quota in ("max", "-1") or not period:
            return None
        value = int(quota) / int(period)
    except (OSError, ValueError, ZeroDivisionError):
        return None
    return value if value > 0 else None


def cgroup_cpu_limit(
    cgroup_root: str | os.PathLike | None = None,
    proc_cgroup: str | os.PathLike = "/proc/self/cgroup",
) -> float | None:
    """CPUs the cgroup CPU quota allows this process (cgroup v2 or v1, the tightest limit
    on its cgroup or any above it); None without one. `cgroup_root` (default
    $COADAPT_CGROUP_ROOT, else /sys/fs/cgroup) is where the cgroup files are mounted,
    `proc_cgroup` the file naming the process's cgroups."""
    root = Path(cgroup_root or os.environ.get(ENV_CGROUP_ROOT) or CGROUP_ROOT)
    limits = []
    for controllers, path in _own_cgroups(os.fspath(proc_cgroup)):
        if not controllers:  # v2: one unified tree
            limits += [_read_limit(folder / "cpu.max") for folder in _folders(root, path)]
        elif "cpu" in controllers.split(","):  # v1: the cpu controller's own tree
            for base in (root / controllers, root / "cpu", root / "cpu,cpuacct"):
                limits += [
                    _read_limit(folder / "cpu.cfs_quota_us", folder / "cpu.cfs_period_us")
                    for folder in _folders(base, path)
                ]
    found = [limit for limit in limits if limit is not None]
    return min(found) if found else None


def affinity_cpus() -> int:
    """CPU cores this process may run on (its affinity mask where the OS has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not on Linux
        return os.cpu_count() or 1


def usable_cpus(cgroup_root: str | os.PathLike | None = None) -> int:
    """CPUs this process may use: its affinity mask's cores, fewer when a cgroup CPU quota
    allows fewer (a quota of 1.5 CPUs: 2 threads); at least 1."""
    cpus = affinity_cpus()
    limit = cgroup_cpu_limit(cgroup_root)
    if limit is not None:
        cpus = min(cpus, math.ceil(limit))
    return max(1, cpus)


def check_threads(value: Any, field: str = "threads") -> int:
    """A thread count: a whole number >= 1 (one line naming `field` otherwise)."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise UserError(f"{field} must be a whole number >= 1, got {value!r}", field=field)
    return int(value)


def apply_threads(n: int | None = None) -> int:
    """Give torch (`torch.set_num_threads`) and the physics (the simulators' default thread
    count, `budget()`) `n` threads (None: `usable_cpus()`); returns the number given."""
    global _budget
    n = usable_cpus() if n is None else check_threads(n)
    _budget = n
    import torch

    torch.set_num_threads(n)
    return n


def share_cores(
    cores: int, cells: int, workers: int | None = None, threads: int | None = None
) -> tuple[int, int]:
    """(cells at once, threads per cell) for a local grid of `cells` cells on `cores` CPUs,
    so that cells at once x threads per cell <= cores: left out, the cells at once are as many
    as fit (one per core, at most one per cell) and the threads per cell the cores divided
    among them. Given both and over `cores`: a one-line `UserError`."""
    cells, cores = max(1, int(cells)), max(1, int(cores))
    if workers is None:
        workers = min(cells, max(1, cores // threads)) if threads is not None else min(cells, cores)
    at_once = min(workers, cells)
    if threads is None:
        threads = max(1, cores // at_once)
    if threads > cores:
        raise UserError(
            f"--threads {threads} per cell is more than the {cores} CPUs this process may use",
            field="threads",
        )
    if at_once * threads > cores:
        fits = (
            f"--threads {max(1, cores // at_once)}"
            if at_once <= cores
            else f"--workers {cores} --threads 1"
        )
        raise UserError(
            f"--workers {at_once} x --threads {threads} = {at_once * threads} threads "
            f"on {cores} CPUs (cells at once x threads per cell must be <= the CPUs); e.g. {fits}",
            field="threads",
        )
    return workers, threads


def budget() -> int:
    """The threads this process gives the physics and torch: what `apply_threads` set,
    else `usable_cpus()`."""
    return _budget if _budget is not None else usable_cpus()


__all__ = [
    "ENV_CGROUP_ROOT",
    "affinity_cpus",
    "apply_threads",
    "budget",
    "cgroup_cpu_limit",
    "check_threads",
    "share_cores",
    "usable_cpus",
]
