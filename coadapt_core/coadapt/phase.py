"""A training phase in chunks, with a checkpoint between them: `coadapt run` saves the
policy and the loop state every `checkpoint_interactions` interactions of a training phase,
so a phase cut off (a session's end, a lost node, a kill) continues from its last chunk
instead of starting again (a paper-preset phase is 24 M interactions, hours on a CPU).

Each chunk is one `CoadaptationBackend.train` call on the phase's designs: chunk 0 with the
phase's seed (a phase no longer than one chunk trains exactly as before), chunk c with a seed
of its own. A chunk restarts the environments' random streams and episodes from its seed
(`train`'s contract), so what a chunk computes depends only on the checkpointed policy, the
designs and its seed: a run resumed from a mid-phase checkpoint trains what the uninterrupted
run trained, interaction for interaction.

The loop hands itself in as a `PhaseHost`: what a phase reads and calls (the state, the
run folder, the backend, the seeds and the state's checkpoint), nothing more.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

from coadapt_core import phase_progress
from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.coadapt.state import LoopState
from coadapt_core.fitness import CoadaptationBackend, TrainingResult

#: the backend checkpoint of the phase in progress (run folder relative; one file, overwritten)
PARTIAL_CHECKPOINT = "checkpoints/backend-partial.pt"


class PhaseHost(Protocol):
    """What a training phase needs from the loop that runs it (`CoadaptationLoop`)."""

    state: LoopState
    config: CoadaptConfig
    run_dir: Path

    def seed_for(self, *parts: int) -> int: ...

    def get_backend(self) -> CoadaptationBackend: ...

    def checkpoint(self) -> None: ...


def chunk_seed(host: PhaseHost, chunk: int) -> int:
    """The seed of chunk `chunk` of this outer iteration's phase (chunk 0: the phase's own)."""
    outer = host.state.outer
    return host.seed_for(1, outer) if chunk == 0 else host.seed_for(1, outer, chunk)


def train_in_chunks(
    host: PhaseHost, steps: int, heard: Callable[[int, int], None]
) -> TrainingResult:
    """Train the shared policy for `steps` interactions on the state's `train_designs`, in
    chunks of `checkpoint_interactions` (0: one chunk), writing the policy and the state
    (`train_progress`) after every chunk but the last; a state that holds `train_progress`
    (a resumed run) continues after its last chunk, its policy already loaded. `heard(done,
    total)` follows the whole phase. Returns the phase as one `TrainingResult` (its
    interactions and seconds summed, the last chunk's reward, statistics and buffer; `extra`
    adds `chunks` and `resumed_at`, the interactions done before this process)."""
    s = host.state
    every = int(getattr(host.config, "checkpoint_interactions", 0) or 0)
    progress: dict[str, Any] = dict(
        s.train_progress or {"outer": s.outer, "done": 0, "chunk": 0, "seconds": 0.0}
    )
    result: TrainingResult | None = None
    resumed_at = progress["done"]  # interactions this phase had done before this process
    while progress["done"] < steps:
        left = steps - progress["done"]
        offset = progress["done"]
        with phase_progress.listening(
            lambda done, total, offset=offset: heard(offset + done, steps)
        ):
            result = host.get_backend().train(
                s.train_designs,
                min(every, left) if every else left,
                seed=chunk_seed(host, progress["chunk"]),
            )
        progress.update(
            done=progress["done"] + int(result.steps),
            chunk=progress["chunk"] + 1,
            seconds=progress["seconds"] + float(result.seconds),
        )
        if result.steps <= 0:  # a backend that trained nothing: no more chunks to wait for
            break
        if progress["done"] < steps:
            save_mid_phase(host, progress)
    s.train_progress = None
    if result is None:  # resumed with nothing left (cannot happen: the last chunk writes no state)
        return TrainingResult(
            steps=progress["done"], seconds=progress["seconds"], mean_reward=float("nan")
        )
    return TrainingResult(
        steps=progress["done"],
        seconds=progress["seconds"],
        mean_reward=result.mean_reward,
        extra={**result.extra, "chunks": progress["chunk"], "resumed_at": resumed_at},
        buffer=result.buffer,
    )


def save_mid_phase(host: PhaseHost, progress: dict[str, Any]) -> None:
    """The policy (atomically, `PARTIAL_CHECKPOINT`) and then the state pointing at it, so
    a kill at any moment leaves a state whose checkpoint exists."""
    s = host.state
    path = host.run_dir / PARTIAL_CHECKPOINT
    path.parent.mkdir(exist_ok=True)
    t0 = time.perf_counter()
    host.get_backend().save(str(path))
    progress["save_seconds"] = progress.get("save_seconds", 0.0) + time.perf_counter() - t0
    s.backend_checkpoint = PARTIAL_CHECKPOINT
    s.train_progress = dict(progress)
    host.checkpoint()
