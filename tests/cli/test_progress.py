"""Progress bars (tqdm): drawn on a terminal, silent when stderr is redirected."""

from __future__ import annotations

import io

from rough_viewer.cli._progress import FileBars, ProgressBar


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_silent_when_not_a_terminal():
    stream = io.StringIO()
    bar = ProgressBar("grid 0.5 m", stream=stream)
    for i in range(6):
        bar(i, 5)
    bars = FileBars(["a.laz", "b.laz"], stream=stream)
    bars.files[0](10, 10)
    bars.overall(10, 20)
    bars.close()
    assert stream.getvalue() == ""


def test_drawn_on_a_terminal_per_file_and_overall():
    stream = Terminal()
    bars = FileBars(["north.laz", "south.laz"], stream=stream)
    bars.files[0](500, 1000)
    bars.files[0](1000, 1000)
    bars.files[1](1000, 1000)
    bars.overall(2000, 2000)
    bars.close()
    text = stream.getvalue()
    assert "north.laz" in text and "south.laz" in text and "all files" in text
    assert "100%" in text and "2.00k" in text
