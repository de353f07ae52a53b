"""Issue 31 item 7: the Measure tab on a real viser server without a browser, on a
200 m ridge at UTM coordinates: the same point twice is refused, numbering restarts
after Clear, leaving measure mode forgets a first point, and a long measure's line
(whose straight chord runs under the ridge) is drawn at its points and dotted on top."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.app.features.measure import LINE_DOTS, MeasureFeature
from rough_viewer.app.gate import open_server
from rough_viewer.app.server import build_app
from rough_viewer.app.settings import MapSettings
from rough_viewer.io import PointCloud
from tests.app.browser import wait_until
from tests.app.protocol import pick

E0, N0 = 512_000.0, 4_170_000.0


def ridge() -> PointCloud:
    """A 200 m x 60 m hillside at UTM coordinates, 1 m spacing, with a ridge 15 m high
    along x = 100 m (the chord between its two flanks runs under the ground)."""
    x, y = np.meshgrid(np.arange(0.0, 201.0), np.arange(0.0, 61.0), indexing="ij")
    z = 300.0 + 15.0 * np.cos(np.pi * (x - 100.0) / 200.0) ** 2 + 0.3 * y
    xyz = np.column_stack([x.ravel() + E0, y.ravel() + N0, z.ravel()])
    return PointCloud.from_xyz(xyz)


@pytest.fixture
def measuring():
    server, _ = open_server("127.0.0.1", 0, token=None, log=False)
    app = build_app(server, ridge(), prefetch=False, variogram=False,
                    settings=MapSettings(cell_size=10.0), presets=(20.0, 10.0))
    assert app.wait_idle(120)
    m = app.host.feature(MeasureFeature)
    m.on.value = True
    yield app, m
    app.stop()
    server.stop()


def click(app, xyz: np.ndarray) -> None:
    """A click from 100 m straight above the point ``xyz`` (file frame)."""
    local = xyz - app.session.shown.loaded.origin
    assert pick(app, local + [0.0, 0.0, 100.0], (0.0, 0.0, -1.0)) is None  # measure took it


def point(app, east: float, north: float) -> np.ndarray:
    xyz = app.session.shown.loaded.cloud.xyz()
    return xyz[int(np.argmin(np.hypot(xyz[:, 0] - E0 - east, xyz[:, 1] - N0 - north)))]


def test_the_same_point_twice_is_no_measure(measuring):
    app, m = measuring
    a, b = point(app, 20, 30), point(app, 60, 30)
    click(app, a)
    click(app, a)
    assert m.items == [] and m.start is not None
    assert "first point again" in m.note.content
    click(app, b)
    assert [k for k, _d, _n in m.items] == [1]
    assert m.items[0][1].distance_m == pytest.approx(float(np.linalg.norm(b - a)), rel=1e-9)


def test_numbering_restarts_after_clear(measuring):
    app, m = measuring
    a, b, c = point(app, 20, 30), point(app, 60, 30), point(app, 90, 10)
    for p, q in ((a, b), (b, c)):
        click(app, p)
        click(app, q)
    assert [k for k, _d, _n in m.items] == [1, 2] and "**D2**" in m.note.content
    m.clear.value = True
    wait_until(lambda: not m.items and not app.worker.busy, 30, "the measures cleared")
    click(app, a)
    click(app, c)
    assert [k for k, _d, _n in m.items] == [1]
    assert "**D1**" in m.note.content and "D2" not in m.note.content


def test_leaving_measure_mode_forgets_the_first_point(measuring):
    app, m = measuring
    stale, c, d = point(app, 20, 30), point(app, 60, 30), point(app, 90, 10)
    click(app, stale)
    assert m.start is not None and m.pending
    m.on.value = False
    wait_until(lambda: m.start is None and not app.worker.busy, 30, "the first point dropped")
    assert not m.pending and m.items == []
    m.on.value = True
    click(app, c)
    click(app, d)
    assert len(m.items) == 1
    _k, dist, _nodes = m.items[0]
    np.testing.assert_allclose(dist.a, c)
    np.testing.assert_allclose(dist.b, d)
    assert "**D1**" in m.note.content


def test_a_long_measure_over_a_ridge_is_drawn_where_it_is_labelled(measuring):
    app, m = measuring
    a, b = point(app, 30, 30), point(app, 170, 30)  # 140 m apart across the ridge
    click(app, a)
    click(app, b)
    _k, dist, nodes = m.items[0]
    assert dist.distance_m == pytest.approx(140.0, abs=1e-6)
    origin = app.session.shown.loaded.origin
    la, lb = a - origin, b - origin
    line, *dots, label = nodes
    # the line runs between the two points in the display frame (float32: 0.1 mm)
    np.testing.assert_allclose(np.asarray(line.points, dtype=np.float64).reshape(2, 3),
                               np.stack([la, lb]), atol=1e-4)
    # the chord is under the ridge: at mid-span the ground is 15 m above it
    cloud = app.session.shown.loaded.cloud.xyz()
    top = cloud[np.argmin(np.hypot(cloud[:, 0] - E0 - 100, cloud[:, 1] - N0 - 30))]
    assert top[2] - 0.5 * (a[2] + b[2]) > 10.0
    # so it is also dotted on top of the rock, evenly along the same segment
    assert len(dots) == LINE_DOTS
    pos = np.array([d.position for d in dots])
    t = np.arange(LINE_DOTS) / (LINE_DOTS - 1)  # from one point to the other
    np.testing.assert_allclose(pos, la + t[:, None] * (lb - la), atol=1e-6)
    assert all(not d._impl.props.depth_test for d in dots)
    np.testing.assert_allclose(label.position, 0.5 * (la + lb), atol=1e-6)
    assert not label._impl.props.depth_test


def test_a_saved_view_keeps_the_measures_and_serve_view_restores_them(measuring, tmp_path):
    """Issue 31 item 11: views kept no measures; a saved view holds each measure's two
    points and number, and putting the view back on a fresh app lists and draws the
    same distances (against the points' own distance), numbering on after them."""
    import viser

    from rough_viewer.app.views import apply_view, view_of
    from rough_viewer.report.view import InputRef, load_view, save_view

    app, m = measuring
    pairs = [(point(app, 20, 30), point(app, 60, 30)), (point(app, 10, 5), point(app, 190, 50))]
    for a, b in pairs:
        click(app, a)
        click(app, b)
    assert [k for k, *_ in m.items] == [1, 2]
    ref = InputRef(path=str(tmp_path / "ridge.npy"), sha256="0" * 64, size_bytes=1)
    saved = load_view(save_view(tmp_path / "v.json", view_of(app.host, ref, camera=None)),
                      check=False).view
    assert [(mp.number, np.array(mp.start), np.array(mp.end)) for mp in saved.measures] \
        and all(np.array_equal(mp.start, a) and np.array_equal(mp.end, b)
                for mp, (a, b) in zip(saved.measures, pairs, strict=True))
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    other = build_app(server, ridge(), prefetch=False, variogram=False,
                      settings=MapSettings(cell_size=10.0), presets=(20.0, 10.0))
    try:
        assert other.wait_idle(120)
        apply_view(other.host, saved)
        assert other.wait_idle(120) and list(other.host.errors) == []
        n = other.host.feature(MeasureFeature)
        assert [k for k, *_ in n.items] == [1, 2] and n.count == 2
        for (_k, d, nodes), (a, b) in zip(n.items, pairs, strict=True):
            assert d.distance_m == pytest.approx(float(np.linalg.norm(b - a)), rel=1e-12)
            assert len(nodes) == 2 + LINE_DOTS
        assert f"{np.linalg.norm(pairs[1][1] - pairs[1][0]):.4g} m" in n.note.content
        # the next measure is D3
        n.on.value = True
        click(other, pairs[0][0])
        click(other, pairs[0][1])
        assert [k for k, *_ in n.items] == [1, 2, 3]
    finally:
        other.stop()
        server.stop()
