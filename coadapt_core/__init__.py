"""coadapt: co-adaptation of a robot's design and its locomotion policy (Du et al. 2025).

The core holds the interfaces (one abstract base class per plugin kind), the plugin
registry, design spaces, the locomotion task, the learner, the co-adaptation loop, the
results store and the CLI. Robots, simulators, optimizers and objectives are plugins.
"""

from coadapt_core.hookspecs import hookimpl  # pluggy only: torch is not imported yet

__version__ = "0.1.0"
__all__ = ["__version__", "hookimpl"]
