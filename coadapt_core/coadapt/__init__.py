"""The co-adaptation loop (paper Algorithm 4): its settings and presets (config.py), the
parts a run is built from (setup.py), the loop with its resumable state (loop.py, state.py)
and the run's start, resume and summary (run.py, summary.py). Import each name from the
module that defines it."""
