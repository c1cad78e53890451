"""The co-adaptation loop (paper Algorithm 4): config and presets, the loop with its method
switches and resumable state, and the run recorders."""

from coadapt_core.coadapt.config import METHODS, PRESETS, CoadaptConfig, make_config
from coadapt_core.coadapt.loop import (
    METHOD_SWITCHES,
    CoadaptResult,
    MethodSwitches,
    run_coadaptation,
)
from coadapt_core.results.recorders import JsonRecorder, make_recorder, read_evaluations

__all__ = [
    "METHODS",
    "METHOD_SWITCHES",
    "PRESETS",
    "CoadaptConfig",
    "CoadaptResult",
    "JsonRecorder",
    "MethodSwitches",
    "make_config",
    "make_recorder",
    "read_evaluations",
    "run_coadaptation",
]
