"""The physics room: the `Simulator` base every backend extends, and what all backends
share so that sim-to-sim comparisons are honest: the rules of its options and arguments
(`options`), actuation (`actuation`), Table 2 domain randomization and its draw
(`randomization`) and terrains (`terrain`)."""
