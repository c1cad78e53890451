"""The top of the program, above the command line: the `coadapt` console script (`entry`)
and `python -m coadapt_core ...` (for machines where the script is not on PATH, e.g.
packages installed with `pip install --target`, and for `coadapt grid`'s cell processes).

It picks torch's OpenMP wait policy first (`coadapt_core.launch`: libgomp reads it once,
when torch loads it), then imports and runs the command line."""

from __future__ import annotations

import sys

from coadapt_core.launch import apply_omp_wait_policy


def entry() -> None:  # pragma: no cover - console script
    apply_omp_wait_policy()
    from coadapt_core.cli import main

    sys.exit(main())


if __name__ == "__main__":
    entry()
