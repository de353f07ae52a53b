"""Progress bars on the command line (stderr), drawn by tqdm.

The science takes ``progress: Callable[[int, int], None] | None`` callbacks and calls
them with (done, total); this module turns such calls into bars. Bars draw only on
a terminal: when stderr is redirected to a file or pipe they stay silent, so logs
hold no carriage-return clutter.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any, TextIO


def _is_terminal(stream: TextIO) -> bool:
    isatty = getattr(stream, "isatty", None)
    return bool(isatty and isatty())


class ProgressBar:
    """Callable progress bar: ``bar(done, total)`` moves a tqdm bar to ``done``.

    Parameters
    ----------
    label : str
        Text before the bar.
    stream : text stream, optional
        Where to draw (default stderr).
    unit : str
        What is counted (``"pt"`` for points, ``"step"`` for stages).
    position : int, optional
        Line of the bar among several drawn at once (tqdm's ``position``).
    """

    def __init__(self, label: str, *, stream: TextIO | None = None, unit: str = "it",
                 position: int | None = None, leave: bool = True) -> None:
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = _is_terminal(self.stream)
        self._bar: Any = None  # a tqdm bar once drawn (tqdm is imported then)
        self._unit = unit
        self._position = position
        self._leave = leave

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        if self._bar is None:
            from tqdm import tqdm

            self._bar = tqdm(total=total, desc=self.label, file=self.stream, unit=self._unit,
                             unit_scale=self._unit == "pt", position=self._position,
                             leave=self._leave, dynamic_ncols=True, mininterval=0.1)
        bar = self._bar
        if total != bar.total:
            bar.total = total
        bar.update(done - bar.n)
        if total > 0 and done >= total:
            self.close()

    def close(self) -> None:
        """Finish the bar (its line stays on screen)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None


class FileBars:
    """An overall bar and one bar per input file, drawn together.

    ``bars.overall`` and ``bars.files[i]`` are ``progress(done, total)`` callbacks.
    """

    def __init__(self, names: Sequence[str], *, label: str = "all files",
                 stream: TextIO | None = None, overall_unit: str = "pt") -> None:
        self.overall = ProgressBar(label, stream=stream, unit=overall_unit, position=0)
        self.files = [ProgressBar(name, stream=stream, unit="pt", position=i + 1,
                                  leave=False)
                      for i, name in enumerate(names)]

    def close(self) -> None:
        """Finish every bar."""
        for b in self.files:
            b.close()
        self.overall.close()


