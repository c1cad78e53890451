"""The seed of a run's scenario set (`coadapt_core.scenarios`), block by block. Needs
neither torch nor the physics room, so the results room may read it (through
`coadapt_core.fitness`)."""

from __future__ import annotations

import numpy as np


def scenario_seed(run_seed: int, block: int = 0) -> int:
    """The seed of a run's scenario set (block 0: every real round; 1, 2, ...: the final
    check's fresh blocks). `coadapt landscape --seed s`, `coadapt eval --seed s` and the
    report's re-evaluations use the same function, so a run with seed s and those commands
    with seed s evaluate designs on the same scenarios."""
    seq = np.random.SeedSequence([int(run_seed), 7, int(block)])
    return int(seq.generate_state(1)[0] % (2**31 - 1))
