"""coadapt: co-adaptation of a robot's design and its locomotion policy (Du et al. 2025).

The core holds the interfaces (one abstract base class per plugin kind), the plugin
registry, design spaces, the locomotion task, the learner, the co-adaptation loop, the
results store and the CLI. Robots, simulators, optimizers and objectives are plugins.
"""

from typing import Any

__version__ = "0.1.0"
__all__ = ["__version__", "hookimpl"]


def __getattr__(name: str) -> Any:
    """`hookimpl` (pluggy's marker, `coadapt_core.hookspecs`), imported when a plugin first
    asks for it: `coadapt --help` and the commands that load no plugin do not import pluggy."""
    if name == "hookimpl":
        from coadapt_core.hookspecs import hookimpl

        return hookimpl
    raise AttributeError(f"module 'coadapt_core' has no attribute {name!r}")
