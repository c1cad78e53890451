"""The OpenMP wait policy the `coadapt` command picks before torch is imported (libgomp
reads its settings once, when torch loads it).

Importing the library does none of this: only the command's entry point
(`coadapt_core.__main__.entry`: the console script and `python -m coadapt_core`) and the
benchmark scripts that call `apply_omp_wait_policy` before importing torch read /proc and
set the environment."""

from __future__ import annotations

import os
import sys

#: how long (libgomp spin iterations, tens of microseconds) torch's idle OpenMP workers
#: spin before they sleep, on a machine with cores to spare
SPIN_WHEN_IDLE = "30000"


def running_processes() -> int | None:
    """Threads of other processes running or ready to run now, plus one for this process
    (/proc/stat's procs_running less this process's own running threads, such as a numeric
    library's spinning workers; the least of three reads 5 ms apart, so a passing kernel
    thread does not count); None where there is no /proc."""
    import time

    counts = []
    for i in range(3):
        try:
            with open("/proc/stat") as f:
                total = next(int(line.split()[1]) for line in f if line.startswith("procs_running"))
            own = 0
            for tid in os.listdir("/proc/self/task"):
                try:
                    with open(f"/proc/self/task/{tid}/stat") as f:
                        own += f.read().rsplit(")", 1)[1].split()[0] == "R"
                except (OSError, IndexError):
                    continue
        except (OSError, ValueError, IndexError, StopIteration):
            return None
        counts.append(total - own + 1)
        if i < 2:
            time.sleep(0.005)
    return min(counts)


def omp_wait_settings(environ, cores: int, running: int | None) -> dict[str, str]:
    """The OpenMP wait settings for torch's worker threads, chosen before torch is imported
    (libgomp reads them once). Settings the user gave (OMP_WAIT_POLICY or GOMP_SPINCOUNT)
    win. With fewer than half the cores busy besides this process, workers spin briefly
    between parallel regions (the PPO update's thousands of small regions then cost no
    wake-ups: 9 700-9 900 update samples/s against 7 700-8 000 on an idle 2-core machine);
    otherwise they sleep at once, because spinning workers fight other processes for the
    cores (a 2-thread update ran 2x slower beside two busy processes, 8x beside thirty).
    docs/training.md, Throughput."""
    if "OMP_WAIT_POLICY" in environ or "GOMP_SPINCOUNT" in environ:
        return {}
    if running is not None and 2 * (running - 1) < cores:
        return {"GOMP_SPINCOUNT": SPIN_WHEN_IDLE}
    return {"OMP_WAIT_POLICY": "PASSIVE"}


def apply_omp_wait_policy() -> dict[str, str]:
    """Set the wait policy in os.environ (once torch is imported it is too late: then nothing
    is read or set). Returns the settings it added."""
    if "torch" in sys.modules:
        return {}
    from coadapt_core.threads import usable_cpus  # no torch: safe before it loads

    chosen = omp_wait_settings(os.environ, usable_cpus(), running_processes())
    os.environ.update(chosen)
    return chosen
