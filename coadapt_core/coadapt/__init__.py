"""The co-adaptation loop (paper Algorithm 4): config and presets, the method registry, the
loop with its resumable state, and the run recorders."""

from coadapt_core.coadapt.config import PRESETS, CoadaptConfig
from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.run import run_coadaptation
from coadapt_core.coadapt.summary import CoadaptResult
from coadapt_core.methods import METHOD_NAMES, METHODS, Method
from coadapt_core.results.recorders import JsonRecorder, make_recorder, read_evaluations

__all__ = [
    "METHODS",
    "METHOD_NAMES",
    "PRESETS",
    "CoadaptConfig",
    "CoadaptResult",
    "JsonRecorder",
    "Method",
    "make_config",
    "make_recorder",
    "read_evaluations",
    "run_coadaptation",
]
