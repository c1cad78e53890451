"""The top of the program, above the command line: the `coadapt` console script (`entry`)
and `python -m coadapt_core ...` (for machines where the script is not on PATH, e.g.
packages installed with `pip install --target`, and for `coadapt grid`'s cell processes).

For a command that simulates (`coadapt_core.cli.COMMANDS`: run, train, eval, grid, report,
landscape, handoff) it picks torch's OpenMP wait policy first (`coadapt_core.launch`: libgomp
reads it once, when torch loads it), then runs the command line; `coadapt --help`, `coadapt
plugins` and the other commands that load no torch skip that (it reads /proc three times,
5 ms apart)."""

from __future__ import annotations

import sys

from coadapt_core.launch import apply_omp_wait_policy


def simulates(argv: list[str]) -> bool:
    """Whether the command line (the words after `coadapt`) names a command that simulates."""
    from coadapt_core.cli import COMMANDS

    words = [w for w in argv if not w.startswith("-")]  # `coadapt` itself takes flags only
    return bool(words) and words[0] in COMMANDS and COMMANDS[words[0]].simulates


def entry() -> None:  # pragma: no cover - console script
    if simulates(sys.argv[1:]):
        apply_omp_wait_policy()
    from coadapt_core.cli import main

    sys.exit(main())


if __name__ == "__main__":
    entry()
