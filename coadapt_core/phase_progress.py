"""Progress inside a long phase (a training phase of `coadapt run`): whoever runs the phase
listens (`listening`), whatever does the work reports how far it got (`report`), without
either knowing the other. The training runner (`coadapt_core.learning.runner.Runner`)
reports after every PPO iteration; `CoadaptationLoop` listens while its backend trains and
turns each report into a progress event, so a training phase that takes minutes or hours
moves the progress line with its own count and an ETA from its measured rate. A backend
that reports nothing leaves the phase silent but for the progress line's heartbeat.

Listeners are per thread (a context variable): a grid's cells in threads do not hear each
other."""

from __future__ import annotations

import contextlib
import contextvars
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

#: what a listener gets: (interactions done in this phase, interactions the phase will take)
Listener = Callable[[int, int], None]

_LISTENERS: contextvars.ContextVar[tuple[Listener, ...]] = contextvars.ContextVar(
    "phase_listeners", default=()
)


@contextlib.contextmanager
def listening(listener: Listener) -> Iterator[None]:
    """Within: `listener(done, total)` hears every `report`."""
    token = _LISTENERS.set((*_LISTENERS.get(), listener))
    try:
        yield
    finally:
        _LISTENERS.reset(token)


def report(done: int, total: int) -> None:
    """Tell the listeners (if any) that `done` of `total` interactions of the phase are done."""
    for listener in _LISTENERS.get():
        listener(int(done), int(total))


@dataclass
class PhaseRate:
    """The measured rate of one phase: `eta(done, total)` is the seconds left at the rate seen
    since the first report (the phase's start-up, before any report, is not counted as work
    done in no time); None until two reports came."""

    clock: Callable[[], float] = time.perf_counter
    first: tuple[float, int] | None = None

    def eta(self, done: int, total: int) -> float | None:
        now = self.clock()
        if self.first is None:
            self.first = (now, done)
            return None
        t0, d0 = self.first
        if done <= d0 or now <= t0:
            return None
        return max(total - done, 0) * (now - t0) / (done - d0)


__all__ = ["Listener", "PhaseRate", "listening", "report"]
