"""The terrain names every backend understands (paper section 4.4), declared once: the
physics room builds them (`coadapt_core.physics.terrain`), settings offer them and reports
order their rows by them. A plain declaration, so rooms that run no physics can read it."""

from __future__ import annotations

#: terrain names, in the paper's order (flat, slope, random)
TERRAINS: tuple[str, ...] = ("flat", "slope", "random")
