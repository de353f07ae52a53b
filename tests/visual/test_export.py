"""Figures out: PNG and SVG through kaleido, HTML offline, written atomically."""

from __future__ import annotations

import importlib.util
import io
import re
import sys

import plotly.graph_objects as go
import pytest

from rough_viewer.visual.export import (
    check_figure_export,
    figure_bytes,
    figure_format,
    write_figure,
)
from rough_viewer.vocabulary import InputError

HAVE_KALEIDO = importlib.util.find_spec("kaleido") is not None


def _figure() -> go.Figure:
    return go.Figure(go.Scatter(x=[0, 1, 2], y=[3.0, 1.0, 2.0]),
                     layout={"title": {"text": "ODR roughness, grid 0.25 m"}})


def test_html_is_one_offline_page(tmp_path):
    path = write_figure(_figure(), tmp_path / "fig.html")
    text = path.read_text()
    assert text.lower().startswith("<!doctype html>")
    assert "ODR roughness, grid 0.25 m" in text
    assert len(text) > 1_000_000  # plotly.js inlined
    assert not re.search(r"<script[^>]+src=\"https?:", text)  # nothing fetched from a network
    assert [p.name for p in tmp_path.iterdir()] == ["fig.html"]


def test_format_from_suffix():
    assert figure_format("a.PNG") == "png" and figure_format("b.htm") == "html"
    with pytest.raises(InputError, match=r"\.png, \.svg or \.html"):
        figure_format("c.jpg")


def test_missing_kaleido_is_one_line(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "kaleido", None)
    with pytest.raises(InputError, match=r"needs the optional package kaleido"):
        check_figure_export("png")
    with pytest.raises(InputError, match="SVG export needs"):
        write_figure(_figure(), tmp_path / "x.svg")
    check_figure_export("html")
    assert list(tmp_path.iterdir()) == []


def test_render_failure_leaves_no_file(monkeypatch, tmp_path):
    import rough_viewer.visual.export as export_module

    def broken(fig, **kwargs):
        raise RuntimeError("Chrome not found\nmore detail")

    monkeypatch.setattr(export_module, "check_figure_export", lambda fmt: None)
    monkeypatch.setattr(go.Figure, "to_image", broken)
    with pytest.raises(InputError) as info:
        write_figure(_figure(), tmp_path / "x.png")
    assert str(info.value) == "PNG export failed: Chrome not found"
    assert list(tmp_path.iterdir()) == []


def test_a_render_that_fails_once_is_tried_again(monkeypatch, tmp_path):
    """kaleido's browser page can answer before its script is defined on a loaded
    machine: a second render is tried, and only two failures end the export."""
    import rough_viewer.visual.export as export_module

    calls = []

    def flaky(fig, **kwargs):
        calls.append(kwargs["format"])
        if len(calls) == 1:
            raise RuntimeError("ReferenceError: kaleido_scopes is not defined")
        return b"<svg/>"

    monkeypatch.setattr(export_module, "check_figure_export", lambda fmt: None)
    monkeypatch.setattr(go.Figure, "to_image", flaky)
    path = write_figure(_figure(), tmp_path / "x.svg")
    assert calls == ["svg", "svg"] and path.read_bytes() == b"<svg/>"


@pytest.mark.skipif(not HAVE_KALEIDO, reason="kaleido not installed (rough_viewer[images])")
@pytest.mark.slow
def test_png_and_svg_with_kaleido(tmp_path):
    from PIL import Image

    try:
        png = figure_bytes(_figure(), "png", width=400, height=300, scale=2)
    except InputError as exc:  # kaleido present but no browser it can start
        pytest.skip(str(exc))
    image = Image.open(io.BytesIO(png))
    assert image.format == "PNG" and image.size == (800, 600)
    path = write_figure(_figure(), tmp_path / "fig.svg", width=400, height=300)
    svg = path.read_text()
    assert svg.startswith("<svg") and "ODR roughness, grid 0.25 m" in svg


def test_a_zip_of_html_figures_holds_one_plotly_js(tmp_path):
    """Nine HTML figures in a ZIP: one plotly.min.js beside them (each page loads it
    by a relative name, nothing from a network), not nine inlined copies; unpacked,
    a page and the script are side by side."""
    import zipfile

    from plotly.offline import get_plotlyjs

    from rough_viewer.visual.export import PLOTLY_JS_NAME, write_figures_zip

    figures = [(f"fig{k}", _figure()) for k in range(9)]
    steps = []
    buf = io.BytesIO()
    names = write_figures_zip(buf, figures, "html", progress=lambda d, t: steps.append(d))
    assert names == [PLOTLY_JS_NAME] + [f"fig{k}.html" for k in range(9)]
    with zipfile.ZipFile(io.BytesIO(buf.getvalue())) as zf:
        assert zf.namelist() == names
        assert zf.read(PLOTLY_JS_NAME).decode() == get_plotlyjs()
        page = zf.read("fig3.html").decode()
    assert len(page) < 20_000 and f'src="{PLOTLY_JS_NAME}"' in page
    assert not re.search(r"<script[^>]+src=\"https?:", page)
    assert sum(zi.file_size for zi in zipfile.ZipFile(io.BytesIO(buf.getvalue())).infolist()) \
        < 1.2 * len(get_plotlyjs())
    assert steps == list(range(10))


def test_titles_and_formats_for_people(monkeypatch):
    from rough_viewer.visual.export import (
        FORMATS_NOTE,
        figure_formats,
        figure_title,
        formats_note,
    )

    assert figure_title("colour_bar") == "Colour bar"
    assert figure_title("face_scales") == "Whole-face roughness against grid size"
    assert figure_title("zones_new_thing") == "Zones new thing"
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None)
    assert figure_formats() == ("html",) and formats_note() == FORMATS_NOTE
    assert "pip install 'rough_viewer[images]'" in FORMATS_NOTE
