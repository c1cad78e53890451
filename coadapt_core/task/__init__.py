"""The simulator-agnostic locomotion task: commands, gait clock, observations (o in R^70,
xi, critic state), rewards (paper Table 1 plus ours), noise, termination, objective metrics."""
