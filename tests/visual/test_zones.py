"""Tests of rough_viewer.visual.zones: the figures carry the zones' numbers, the poles
and the zone colours."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.grid.orientation import cell_stereonet
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.structure.zones import ZoneLabeller
from rough_viewer.visual import colormaps
from rough_viewer.visual.zones import (
    COMPACT_COLUMNS,
    stereonet_figure,
    zones_map_figure,
    zones_table_figure,
)
from rough_viewer.vocabulary import InputError, hex_to_rgb
from tests.helpers import banded_face

BANDS = [(-1.3, -1.6, 5.0, 0.6, 0.0), (2.3, 1.0, 3.4, 0.6, 60.0)]


@pytest.fixture(scope="module")
def zoned():
    pts, _ = banded_face(50.0, 200.0, BANDS, rough=0.01, n=60_000)
    res = grid_roughness(pts, 0.2)
    return res, ZoneLabeller.build(res).zones(0.2)


def kw(res):
    return {"grid_size": res.grid.cell_size, "axis": res.axis, "n_points": res.n_points_total}


def test_zone_colours_cycle_and_grey_for_none():
    rgb = colormaps.zone_colours(np.array([0, 1, 2, 13]))
    assert tuple(rgb[0]) == colormaps.NEUTRAL_RGB
    assert tuple(rgb[1]) == hex_to_rgb(colormaps.ZONE_PALETTE[0])
    assert tuple(rgb[3]) == tuple(rgb[1])  # 13 = 12 + 1 wraps round
    assert len(set(colormaps.ZONE_PALETTE)) == len(colormaps.ZONE_PALETTE)


def test_table_rows_are_the_zones(zoned):
    res, zones = zoned
    fig = zones_table_figure(zones, selected=2, **kw(res))
    table = fig.data[0]
    cols = table.cells.values
    assert list(cols[0]) == ["<b>1</b>", "<b>2</b>"]
    assert list(cols[1]) == [f"{c:,}" for c in zones.cells]
    assert cols[3][0] == f"{zones.area_m2[0]:.3g}"
    assert cols[7][1] == f"{zones.dip_deg[1]:02.0f} / {zones.dip_direction_deg[1]:03.0f}"
    assert list(table.cells.fill.color[0]) == [colormaps.zone_colour(1), colormaps.zone_colour(2)]
    assert table.cells.fill.color[1][1] != table.cells.fill.color[1][0]  # the selected row
    text = fig.layout.title.text
    assert "2 zones" in text and "ODR normalised ≥ 0.2" in text and "grid 0.2 m" in text
    short = zones_table_figure(zones, max_rows=1, **kw(res))
    assert len(short.data[0].cells.values[0]) == 1 and "largest shown" in short.layout.title.text


def test_map_shows_each_zone_in_its_pixels(zoned):
    res, zones = zoned
    fig = zones_map_figure(zones, res)
    heat = fig.data[0]
    ids = np.asarray(heat.customdata, dtype=float)
    slots = np.asarray(heat.z, dtype=float)
    for zone in (1, 2):
        assert np.count_nonzero(ids == zone) > 0
        # the colour slot of a zone is its place in the palette (1-based)
        assert np.all(slots[ids == zone] == zone)
    assert np.all(slots[ids == 0] == 0) and np.isnan(slots).sum() == np.isnan(ids).sum()


def test_stereonet_draws_every_pole_and_the_highlighted_zone(zoned):
    res, zones = zoned
    net = cell_stereonet(res)
    fig = stereonet_figure(net, highlight={"zone 1": zones.labels == 1}, **kw(res))
    contour, poles, zone1 = fig.data[0], fig.data[1], fig.data[2]
    assert contour.type == "contour"
    np.testing.assert_array_equal(poles.x, net.x)
    np.testing.assert_array_equal(poles.y, net.y)
    on = np.isin(net.rows, np.flatnonzero(zones.labels == 1))
    np.testing.assert_array_equal(zone1.x, net.x[on])
    assert zone1.marker.color == colormaps.ZONE_PALETTE[0]
    assert zone1.name == f"zone 1 ({zones.cells[0]:,})"
    # hover: the plane of each pole, near the face's dip 50 / direction 200
    dip_dd = np.asarray(zone1.customdata)
    assert np.median(dip_dd[:, 0]) == pytest.approx(50.0, abs=2.0)
    assert np.median(dip_dd[:, 1]) == pytest.approx(200.0, abs=2.0)
    # the same subset given as rows; at most max_poles drawn
    rows_fig = stereonet_figure(net, highlight={"z": np.flatnonzero(zones.labels == 1)},
                                max_poles=10, **kw(res))
    assert len(rows_fig.data[1].x) == 10 and len(rows_fig.data[2].x) == 10
    assert "lower hemisphere, equal area" in fig.layout.title.text


def test_compact_table_and_legend_counts(zoned):
    res, zones = zoned
    fig = zones_table_figure(zones, columns=COMPACT_COLUMNS, **kw(res))
    table = fig.data[0]
    assert list(table.header.values) == ["zone", "cells", "area (m²)", "length × width (m)",
                                         "trace (az/plunge °)", "dip / direction (°)",
                                         "mean θ (mm)"]
    assert table.cells.values[3][0] == f"{zones.length_m[0]:.3g} × {zones.width_m[0]:.3g}"
    with pytest.raises(InputError):
        zones_table_figure(zones, columns=("cells", "zone"), **kw(res))
    with pytest.raises(InputError):
        zones_table_figure(zones, columns=("zone", "colour"), **kw(res))
    # a legend counts every pole of a subset, also when fewer are drawn
    net = cell_stereonet(res)
    fig = stereonet_figure(net, highlight={"zone 1": zones.labels == 1}, max_poles=10, **kw(res))
    n1 = int(np.isin(net.rows, np.flatnonzero(zones.labels == 1)).sum())
    assert n1 > 10 and len(fig.data[2].x) == 10 and fig.data[2].name == f"zone 1 ({n1:,})"


def test_azimuths_are_written_in_000_to_359():
    from rough_viewer.visual.zones import azimuth_text

    assert [azimuth_text(a) for a in (0.0, 5.2, 89.6, 359.4, 359.7, 360.0)] == \
        ["000", "005", "090", "359", "000", "000"]


def test_figures_follow_the_unit(zoned):
    """A cloud in millimetres or feet: lengths, areas and the caption in its unit,
    roughness in mm for metric input and in feet for feet."""
    from rough_viewer.app.features.zones import zone_markdown
    from rough_viewer.app.units import Units

    res, zones = zoned
    mm = zones_table_figure(zones, unit="mm", **kw(res))
    header = list(mm.data[0].header.values)
    cols = mm.data[0].cells.values
    assert header[3:6] == ["area (mm²)", "length (mm)", "width (mm)"]
    assert cols[3][0] == f"{zones.area_m2[0] * 1e6:.3g}"
    assert cols[4][1] == f"{zones.length_m[1] * 1e3:.3g}"
    assert header[8] == "mean θ (mm)" and cols[8][0] == f"{zones.mean_theta[0] * 1e3:.3g}"
    assert "grid 200 mm" in mm.layout.title.text
    ft = zones_table_figure(zones, unit="ft", **kw(res))
    assert list(ft.data[0].header.values)[8] == "mean θ (ft)"
    assert ft.data[0].cells.values[8][0] == f"{zones.mean_theta[0] / 0.3048:.3g}"
    face = zones_map_figure(zones, res, unit="ft")
    plain = zones_map_figure(zones, res)
    np.testing.assert_allclose(np.asarray(face.data[0].x), np.asarray(plain.data[0].x) / 0.3048)
    assert face.layout.xaxis.title.text == "u, along the face (ft)"
    text = zone_markdown(zones, 1, Units("ft")).replace("\\", "")  # md() escapes
    assert f"{zones.length_m[0] / 0.3048:.3g} × {zones.width_m[0] / 0.3048:.3g} ft" in text
    assert f"{zones.area_m2[0] / 0.3048**2:.3g} ft²" in text
    with pytest.raises(InputError, match="unknown unit"):
        zones_table_figure(zones, unit="furlong", **kw(res))
