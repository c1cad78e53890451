"""coadapt: co-adaptation of a robot's design and its locomotion policy (Du et al. 2025).

The core holds the interfaces (one abstract base class per plugin kind), the plugin
registry, design spaces, the locomotion task, the learner, the co-adaptation loop, the
results store and the CLI. Robots, simulators, optimizers and objectives are plugins.
"""

import os
import sys

from coadapt_core.hookspecs import hookimpl  # pluggy only: torch is not imported yet

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
    otherwise they sleep at
    once, because spinning workers fight other processes for the cores (a 2-thread update
    ran 2x slower beside two busy processes, 8x beside thirty). docs/training.md, Throughput."""
    if "OMP_WAIT_POLICY" in environ or "GOMP_SPINCOUNT" in environ:
        return {}
    if running is not None and 2 * (running - 1) < cores:
        return {"GOMP_SPINCOUNT": SPIN_WHEN_IDLE}
    return {"OMP_WAIT_POLICY": "PASSIVE"}


def _usable_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


if "torch" not in sys.modules:
    os.environ.update(omp_wait_settings(os.environ, _usable_cores(), running_processes()))


__version__ = "0.1.0"
__all__ = ["__version__", "hookimpl"]
