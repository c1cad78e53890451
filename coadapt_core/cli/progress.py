"""Progress for long commands: elapsed time and ETA on one line. On a terminal a rich bar
whose fields fit 80 columns (the free text is cut, never the numbers); when the output is a
file or a pipe, a plain line every `every` seconds and at the end, so logs show progress."""

from __future__ import annotations

import math
import sys
import time
from typing import Any, TextIO


def fmt_duration(seconds: float | None) -> str:
    """h:mm:ss, or '?' when unknown."""
    if seconds is None or not math.isfinite(seconds) or seconds < 0:
        return "?"
    seconds = int(round(seconds))
    return f"{seconds // 3600}:{seconds % 3600 // 60:02d}:{seconds % 60:02d}"


class ProgressLine:
    """`update(done, detail)` of `total` steps (a fraction when total is 1.0); ETA from the
    elapsed time and the fraction done. Use as a context manager."""

    def __init__(self, label: str, total: float | None, *, stream: TextIO | None = None, every: float = 10.0,
                 enabled: bool = True, unit: str = ""):
        self.label = label
        self.total = total
        self.stream = stream or sys.stderr
        self.every = every
        self.enabled = enabled
        self.unit = unit
        self.start = time.perf_counter()
        self.done = 0.0
        self.detail = ""
        self._last_plain = -math.inf
        self._rich = None
        self._task = None
        self.interactive = bool(getattr(self.stream, "isatty", lambda: False)())

    # -- numbers ----------------------------------------------------------------------------
    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self.start

    @property
    def fraction(self) -> float | None:
        if not self.total:
            return None
        return min(max(self.done / self.total, 0.0), 1.0)

    @property
    def eta(self) -> float | None:
        f = self.fraction
        if f is None or f <= 0:
            return None
        return self.elapsed * (1 - f) / f

    def counts(self) -> str:
        if self.total is None:
            return ""
        if self.total == 1.0 and not self.unit:
            return f"{100 * (self.fraction or 0):3.0f}%"
        return f"{self.done:g}/{self.total:g}{self.unit}"

    def plain_line(self) -> str:
        parts = [self.label, self.counts(), f"elapsed {fmt_duration(self.elapsed)}"]
        if self.total is not None:
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
            TextColumn("{task.fields[detail]}", table_column=Column(ratio=1, no_wrap=True, overflow="ellipsis")),
            console=Console(file=self.stream),
            transient=False,
            expand=True,
        )
        self._rich.__enter__()
        self._task = self._rich.add_task(self.label, total=self.total or None, label=self.label, counts="",
                                         eta="?", detail="")

    def update(self, done: float | None = None, detail: str | None = None, *, total: float | None = None) -> None:
        if total is not None:
            self.total = total
        if done is not None:
            self.done = float(done)
        if detail is not None:
            self.detail = detail
        if not self.enabled:
            return
        if self.interactive:
            if self._rich is None:
                self._start_rich()
            self._rich.update(self._task, completed=self.done, total=self.total or None, counts=self.counts(),
                              eta=fmt_duration(self.eta), detail=self.detail)
        elif time.perf_counter() - self._last_plain >= self.every:
            self._emit_plain()

    def _emit_plain(self) -> None:
        self._last_plain = time.perf_counter()
        self._last_text = self.plain_line()
        print(self._last_text, file=self.stream, flush=True)

    def close(self) -> None:
        if not self.enabled:
            return
        if self._rich is not None:
            self._rich.__exit__(None, None, None)
            self._rich = None
        elif not self.interactive and self.counts() not in getattr(self, "_last_text", self.counts()):
            self._emit_plain()  # the last state, whatever the period

    def __exit__(self, *exc: Any) -> None:
        self.close()


__all__ = ["ProgressLine", "fmt_duration"]
