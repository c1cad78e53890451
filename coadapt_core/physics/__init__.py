"""The physics room: the `Simulator` base every backend extends, and what all backends
share so that sim-to-sim comparisons are honest: actuation (`actuation`), Table 2 domain
randomization (`randomization`) and terrains (`terrain`)."""
