"""Figures out: any plotly figure as PNG or SVG (through the optional package kaleido,
``pip install 'rough_viewer[images]'``) or as one self-contained HTML page (plotly.js
inlined: opens offline), written atomically through :mod:`rough_viewer.io.output`.

The app's Export folder and the command line call these; :func:`figure_bytes` gives
the content without a file, for a browser download. :func:`write_figures_zip` packs
several figures in one ZIP with ONE copy of plotly.js beside the HTML pages (each
page inlining its own copy made a ZIP of nine figures nine times 4.8 MB);
:func:`figure_title` gives a figure's name for people; :func:`figure_formats` and
:func:`formats_note` say which formats this installation offers and why.
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import warnings
import zipfile
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import IO, Any, Literal

from rough_viewer.io.output import write_atomic
from rough_viewer.vocabulary import InputError, error_line

FigureFormat = Literal["png", "svg", "html"]
FIGURE_FORMATS: tuple[FigureFormat, ...] = ("png", "svg", "html")

#: Pixel density of PNG exports (2 = sharp on paper and on high-density screens).
PNG_SCALE = 2.0

MIME_TYPES: dict[str, str] = {"png": "image/png", "svg": "image/svg+xml",
                              "html": "text/html; charset=utf-8"}


def figure_format(path: str | os.PathLike[str]) -> FigureFormat:
    """The format named by a file's suffix (``.png``, ``.svg``, ``.html``/``.htm``)."""
    suffix = Path(path).suffix.lower().lstrip(".")
    if suffix == "htm":
        suffix = "html"
    if suffix not in FIGURE_FORMATS:
        raise InputError(f"figure file must end in .png, .svg or .html, got {path}")
    return suffix


@contextlib.contextmanager
def image_session(fmt: FigureFormat = "png") -> Iterator[None]:
    """Keep one browser open for the PNG/SVG exports inside the block (kaleido's
    persistent server, kaleido >= 1.1): a figure then takes about 0.1 s instead of
    the ~2 s of starting Chromium for each. Does nothing for HTML, without kaleido,
    with an older kaleido, or inside another session (the outer one closes it)."""
    global _SESSION_OPEN
    kaleido = None
    if fmt in ("png", "svg") and not _SESSION_OPEN and importlib.util.find_spec("kaleido"):
        import kaleido as _kaleido

        if hasattr(_kaleido, "start_sync_server"):
            kaleido = _kaleido
    if kaleido is None:
        yield
        return
    with warnings.catch_warnings():
        # plotly notes that its per-call options are ignored by a running server
        warnings.filterwarnings("ignore", message=".*kopts.*", category=UserWarning)
        try:
            kaleido.start_sync_server(silence_warnings=True)
        except Exception:  # no browser it can start: each export then says why
            yield
            return
        _SESSION_OPEN = True
        try:
            yield
        finally:
            _SESSION_OPEN = False
            try:
                kaleido.stop_sync_server(silence_warnings=True)
            except Exception:  # pragma: no cover - closing a dead browser
                pass


_SESSION_OPEN = False


def check_figure_export(fmt: FigureFormat) -> None:
    """Raise InputError (one line) when ``fmt`` needs kaleido and it is not installed;
    call before any work."""
    if fmt not in FIGURE_FORMATS:
        raise InputError(f"unknown figure format {fmt!r}; expected one of {', '.join(FIGURE_FORMATS)}")
    if fmt in ("png", "svg") and importlib.util.find_spec("kaleido") is None:
        raise InputError(f"{fmt.upper()} export needs the optional package kaleido "
                         "(pip install 'rough_viewer[images]'); HTML export does not")


#: Renders tried before an image export fails: kaleido starts a browser for each, and
#: on a loaded machine its page has answered before its script was defined
#: ("ReferenceError: kaleido_scopes is not defined"), once in a run of the suite.
RENDER_TRIES = 2


def figure_bytes(
    fig: Any,
    fmt: FigureFormat,
    *,
    width: int | None = None,
    height: int | None = None,
    scale: float = PNG_SCALE,
) -> bytes:
    """The file content of a plotly figure as PNG, SVG or HTML.

    Parameters
    ----------
    fig : plotly.graph_objects.Figure
        The figure.
    fmt : {"png", "svg", "html"}
        PNG and SVG need kaleido (and a Chromium it can start); HTML is one
        self-contained page with plotly.js inlined.
    width, height : int, optional
        Size in CSS pixels (PNG/SVG); default the figure's layout size or plotly's.
    scale : float
        Pixel density of PNG (2 doubles the pixels).

    Raises
    ------
    InputError
        kaleido missing, or the image renderer failed (one line).
    """
    check_figure_export(fmt)
    if fmt == "html":
        text = fig.to_html(full_html=True, include_plotlyjs=True,
                           config={"displaylogo": False, "responsive": True})
        return str(text).encode("utf-8")
    size = {k: v for k, v in (("width", width), ("height", height)) if v is not None}
    msg = ""
    for _ in range(RENDER_TRIES):
        try:
            data = fig.to_image(format=fmt, scale=scale if fmt == "png" else 1.0, **size)
        except Exception as exc:  # kaleido and its browser raise many types
            msg = error_line(exc)
            continue
        return bytes(data)
    raise InputError(f"{fmt.upper()} export failed: {msg}")


def write_figure(
    fig: Any,
    path: str | os.PathLike[str],
    *,
    fmt: FigureFormat | None = None,
    width: int | None = None,
    height: int | None = None,
    scale: float = PNG_SCALE,
) -> Path:
    """Write a plotly figure as PNG, SVG or HTML, atomically (a failure leaves no file).

    The format is ``fmt`` or, by default, the file's suffix. Check the path first with
    :func:`rough_viewer.io.output.check_output_path` (existing files, symlinks, the
    chosen folder); this function only writes.

    Returns
    -------
    Path
        ``path``.
    """
    p = Path(path)
    kind = fmt or figure_format(p)
    data = figure_bytes(fig, kind, width=width, height=height, scale=scale)
    write_atomic(p, lambda fh: fh.write(data), mode="wb")
    return p


#: Titles of the app's and the report's figures, by the names they are exported under.
FIGURE_TITLES: dict[str, str] = {
    "colour_bar": "Colour bar",
    "scales": "Roughness of the picked point against grid size",
    "histogram": "Histogram of normalised roughness",
    "variogram": "Semivariograms",
    "summary": "Table 1: summary statistics",
    "face_scales": "Whole-face roughness against grid size",
    "profile": "Profiles and roughness length",
    "bias": "Scanner bias",
    "zones_table": "Zones table",
    "zones_stereonet": "Stereonet of cell poles",
    "zones_map": "Zones on the face",
    "stereonet": "Stereonet of cell poles",
    "maps_normalised": "Face maps of normalised roughness",
    "maps_binary": "Face maps of the binary transform",
}

#: The one copy of plotly.js in a ZIP of HTML figures, beside the pages.
PLOTLY_JS_NAME = "plotly.min.js"

#: Why PNG and SVG are not offered without kaleido (for the export control's note).
FORMATS_NOTE = ("PNG and SVG need the optional package kaleido: "
                "pip install 'rough_viewer[images]'; HTML needs nothing")


def figure_title(name: str) -> str:
    """A figure's name for people: :data:`FIGURE_TITLES`, else the name with spaces.

    >>> figure_title("face_scales"), figure_title("board_offsets")
    ('Whole-face roughness against grid size', 'Board offsets')
    """
    return FIGURE_TITLES.get(name) or name.replace("_", " ").strip().capitalize()


def figure_formats() -> tuple[FigureFormat, ...]:
    """The formats this installation can write: HTML always, PNG and SVG with kaleido."""
    if importlib.util.find_spec("kaleido") is None:
        return ("html",)
    return ("html", "png", "svg")


def formats_note() -> str | None:
    """:data:`FORMATS_NOTE` when PNG and SVG are not offered, else None."""
    return None if "png" in figure_formats() else FORMATS_NOTE


def write_figures_zip(
    fh: IO[bytes],
    figures: Sequence[tuple[str, Any]],
    fmt: FigureFormat,
    *,
    progress: Callable[[int, int], None] | None = None,
) -> list[str]:
    """Write several figures into one ZIP on the open binary file ``fh``: each as
    ``<name>.<fmt>``; for HTML, the pages load ``plotly.min.js`` from beside them and
    the ZIP holds that one copy (unpacked, the folder opens offline). Returns the
    names written.

    Parameters
    ----------
    fh : binary file
        Where the ZIP goes (e.g. inside :func:`rough_viewer.io.output.write_atomic`).
    figures : sequence of (name, plotly figure)
        File names without suffix, and the figures.
    fmt : {"html", "png", "svg"}
        One format for all.
    progress : callable, optional
        ``progress(done, total)`` in figures.
    """
    check_figure_export(fmt)
    names: list[str] = []
    tick = progress or (lambda done, total: None)
    with zipfile.ZipFile(fh, "w", compression=zipfile.ZIP_DEFLATED) as zf, image_session(fmt):
        if fmt == "html":
            from plotly.offline import get_plotlyjs

            zf.writestr(PLOTLY_JS_NAME, get_plotlyjs())
            names.append(PLOTLY_JS_NAME)
        for k, (name, fig) in enumerate(figures):
            tick(k, len(figures))
            if fmt == "html":
                data = str(fig.to_html(full_html=True, include_plotlyjs=PLOTLY_JS_NAME,
                                       config={"displaylogo": False, "responsive": True}))
                zf.writestr(f"{name}.html", data)
            else:
                zf.writestr(f"{name}.{fmt}", figure_bytes(fig, fmt))
            names.append(f"{name}.{fmt}")
        tick(len(figures), len(figures))
    return names
