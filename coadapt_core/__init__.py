"""coadapt: co-adaptation of a robot's design and its locomotion policy (Du et al. 2025).

The core holds the interfaces (one abstract base class per plugin kind), the plugin
registry, design spaces, the locomotion task, the learner, the co-adaptation loop, the
results store and the CLI. Robots, simulators, optimizers and objectives are plugins.
"""

import os

# torch's OpenMP workers sleep between parallel regions instead of spin-waiting (libgomp reads
# this when torch is first imported, so it is set before anything imports torch). With the
# physics backend's threads and other processes sharing a few cores, spinning workers made
# a 2-thread PPO update 8x slower than sleeping ones (docs/training.md, Throughput); on a
# quiet machine the difference is within noise. A value set by the user wins.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from coadapt_core.hookspecs import hookimpl

__version__ = "0.1.0"
__all__ = ["__version__", "hookimpl"]
