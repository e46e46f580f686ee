"""Progress that suits where it goes (issue 40 item 3): a tqdm bar when stderr is a terminal; in a file or a pipe, a
few plain lines (at every tenth of the work and at the end) instead of a bar's every redraw.

``progress_bar(total, desc, unit)`` returns an object with tqdm's ``update(n)`` and ``close()``.
"""

from __future__ import annotations

import sys


class PlainProgress:
    """``desc: k/total unit`` on stderr when k crosses each tenth of ``total`` and at ``close()`` (at most 11 lines)."""

    def __init__(self, total: int, desc: str, unit: str, initial: int = 0) -> None:
        self.total, self.desc, self.unit, self.n = int(total), desc, unit, int(initial)
        self._next = self._step_after(self.n)
        self._closed = False

    def _step_after(self, n: int) -> int:
        tenth = max(self.total // 10, 1)
        return (n // tenth + 1) * tenth

    def _say(self) -> None:
        print(f"{self.desc}: {self.n}/{self.total} {self.unit}s", file=sys.stderr, flush=True)

    def update(self, n: int = 1) -> None:
        self.n += int(n)
        if self.n >= self._next and self.n < self.total:
            self._say()
            self._next = self._step_after(self.n)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._say()


def progress_bar(total: int, desc: str, unit: str, initial: int = 0):
    """A tqdm bar on a terminal, :class:`PlainProgress` otherwise (a log file, a pipe, a CI job)."""
    isatty = getattr(sys.stderr, "isatty", None)
    if callable(isatty) and isatty():
        from tqdm.auto import tqdm

        return tqdm(total=total, initial=initial, desc=desc, unit=unit)
    return PlainProgress(total, desc, unit, initial)
