"""Progress for long commands: elapsed time and ETA on one line. On a terminal a rich bar
whose fields fit 80 columns (the free text is cut, never the numbers); when the output is a
file or a pipe, a plain line every `every` seconds (10; $COADAPT_PROGRESS_EVERY) and at the
end, and a heartbeat in between: a long phase that reports nothing (a training phase, the
video render) still prints its line every `every` seconds, so a log is never silent longer."""

from __future__ import annotations

import math
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, TextIO


def fmt_duration(seconds: float | None) -> str:
    """h:mm:ss, or '?' when unknown."""
    if seconds is None or not math.isfinite(seconds) or seconds < 0:
        return "?"
    seconds = int(round(seconds))
    return f"{seconds // 3600}:{seconds % 3600 // 60:02d}:{seconds % 60:02d}"


#: seconds between plain lines (a pipe or a file); COADAPT_PROGRESS_EVERY overrides it
EVERY = 10.0


def default_every() -> float:
    """COADAPT_PROGRESS_EVERY (seconds, > 0) when set to a number, else `EVERY`."""
    import os

    try:
        value = float(os.environ.get("COADAPT_PROGRESS_EVERY", EVERY))
    except ValueError:
        return EVERY
    return value if math.isfinite(value) and value > 0 else EVERY


#: the share of the work that must be seen done (in this process) before the fraction alone
#: gives an ETA: the first updates come after start-up costs and would extrapolate them
MIN_FRACTION_FOR_ETA = 0.02


class ProgressLine:
    """`update(done, detail)` of `total` steps (a fraction when total is 1.0). The ETA is the
    caller's own estimate when it gives one (`update(eta=seconds)`, counted down between
    updates), else extrapolated from the rate seen in this process (so a resumed command
    does not count the work done before it as done in no time). Use as a context manager.
    With `own_eta` the ETA is only ever the caller's ("?" while it gives None). `clock` is
    for tests (a fake clock); `heartbeat=False` prints only on updates."""

    def __init__(
        self,
        label: str,
        total: float | None,
        *,
        stream: TextIO | None = None,
        every: float | None = None,
        enabled: bool = True,
        unit: str = "",
        clock: Callable[[], float] = time.perf_counter,
        heartbeat: bool = True,
        own_eta: bool = False,
    ):
        self.label = label
        self.total = total
        self.stream = stream or sys.stderr
        self.every = every if every is not None else default_every()
        self.enabled = enabled
        self.unit = unit
        self.clock = clock
        self.own_eta = own_eta
        self.start = clock()
        self.done = 0.0
        self.detail = ""
        self._last_plain = -math.inf
        self._last_text: str | None = None
        self._first: tuple[float, float] | None = None  # (time, fraction) of the first update
        self._eta: tuple[float, float] | None = None  # (caller's ETA, time it was given)
        self._rich = None
        self._task = None
        self._closed = False
        self._lock = threading.Lock()
        self.interactive = bool(getattr(self.stream, "isatty", lambda: False)())
        self._stop = threading.Event()
        self._beat: threading.Thread | None = None
        if enabled and heartbeat and not self.interactive:
            self._beat = threading.Thread(
                target=self._heartbeat_loop, name=f"progress-{label}", daemon=True
            )
            self._beat.start()

    # -- numbers ----------------------------------------------------------------------------
    @property
    def elapsed(self) -> float:
        return self.clock() - self.start

    @property
    def fraction(self) -> float | None:
        if not self.total:
            return None
        return min(max(self.done / self.total, 0.0), 1.0)

    @property
    def eta(self) -> float | None:
        now = self.clock()
        if self._eta is not None:
            return max(self._eta[0] - (now - self._eta[1]), 0.0)
        f = self.fraction
        if self.own_eta:
            return None
        if f is None or self._first is None:
            return None
        t0, f0 = self._first
        if f >= 1.0:
            return 0.0
        if f - f0 < MIN_FRACTION_FOR_ETA or now <= t0:
            return None
        return (now - t0) * (1 - f) / (f - f0)

    def counts(self) -> str:
        if self.total is None:
            return ""
        if self.total == 1.0 and not self.unit:
            return f"{100 * (self.fraction or 0):3.0f}%"
        return f"{self.done:g}/{self.total:g}{self.unit}"

    def plain_line(self) -> str:
        parts = [self.label, self.counts(), f"elapsed {fmt_duration(self.elapsed)}"]
        if self.total is not None or self._eta is not None:
            parts.append(f"ETA {fmt_duration(self.eta)}")
        if self.detail:
            parts.append(self.detail)
        return "  ".join(p for p in parts if p)

    # -- output -----------------------------------------------------------------------------
    def __enter__(self) -> ProgressLine:
        return self

    def _start_rich(self) -> None:
        from rich.console import Console
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
        from rich.table import Column

        self._rich = Progress(
            TextColumn("[bold]{task.fields[label]}"),
            BarColumn(bar_width=12),
            TextColumn("{task.fields[counts]}"),
            TimeElapsedColumn(),
            TextColumn("ETA {task.fields[eta]}"),
            # the free text takes what is left of the line and is cut, never wrapped
            TextColumn(
                "{task.fields[detail]}",
                table_column=Column(ratio=1, no_wrap=True, overflow="ellipsis"),
            ),
            console=Console(file=self.stream),
            transient=False,
            expand=True,
        )
        self._rich.__enter__()
        self._task = self._rich.add_task(
            self.label, total=self.total or None, label=self.label, counts="", eta="?", detail=""
        )

    def update(
        self,
        done: float | None = None,
        detail: str | None = None,
        *,
        total: float | None = None,
        eta: float | None = None,
    ) -> None:
        if total is not None:
            self.total = total
        if done is not None:
            self.done = float(done)
        if detail is not None:
            self.detail = detail
        now = self.clock()
        if eta is not None:
            self._eta = (float(eta), now)
        elif self.own_eta:
            self._eta = None
        if self._first is None and self.fraction is not None:
            self._first = (now, self.fraction)
        if not self.enabled or self._closed:
            return
        if self.interactive:
            if self._rich is None:
                self._start_rich()
            self._rich.update(
                self._task,
                completed=self.done,
                total=self.total or None,
                counts=self.counts(),
                eta=fmt_duration(self.eta),
                detail=self.detail,
            )
        elif now - self._last_plain >= self.every:
            self._emit_plain()

    def heartbeat(self) -> bool:
        """Print the line again if nothing was printed for `every` seconds (plain output);
        True when it printed. The heartbeat thread calls this about once a second."""
        if not self.enabled or self.interactive or self._closed:
            return False
        last = self._last_plain if self._last_plain > -math.inf else self.start
        if self.clock() - last >= self.every:
            self._emit_plain()
            return True
        return False

    def _heartbeat_loop(self) -> None:
        while not self._stop.wait(min(1.0, self.every / 4)):
            try:
                self.heartbeat()
            except (OSError, ValueError):  # the stream was closed under us
                return

    def _emit_plain(self) -> None:
        with self._lock:
            self._last_plain = self.clock()
            self._last_text = self.plain_line()
            print(self._last_text, file=self.stream, flush=True)

    def close(self) -> None:
        self._stop.set()
        if not self.enabled or self._closed:
            self._closed = True
            return
        if self._rich is not None:
            self._rich.__exit__(None, None, None)
            self._rich = None
        elif (
            not self.interactive
            and self._last_text is not None
            and self.counts() not in self._last_text
        ):
            self._emit_plain()  # the last state, whatever the period
        self._closed = True

    def __exit__(self, *exc: Any) -> None:
        self.close()


__all__ = ["EVERY", "MIN_FRACTION_FOR_ETA", "ProgressLine", "default_every", "fmt_duration"]
