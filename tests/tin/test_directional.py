"""theta*max/(C+1) and Delta-T: against a per-triangle reference on small meshes and
against closed forms on planar sawtooth surfaces (issue 25)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rough_viewer.grid.maps import FacePlane
from rough_viewer.io.formats.mesh import TriangleMesh
from rough_viewer.tin.directional import (
    apparent_dips,
    azimuths,
    directional_roughness,
    fit_c,
    window_roughness,
)
from rough_viewer.tin.surface import facets, triangulate_cloud
from rough_viewer.vocabulary import InputError
from tests.tin.reference import surface_reference, window_reference

AZIMUTHS = [0.0, 37.0, 90.0, 161.0, 180.0, 271.0]


def grid_mesh(z: np.ndarray, spacing: float = 1.0) -> TriangleMesh:
    """A regular grid of heights ``z[row, col]`` (x = col, y = row) as two triangles
    per square, alternating diagonals so both orientations occur."""
    rows, cols = z.shape
    yy, xx = np.mgrid[0:rows, 0:cols] * spacing
    i = np.arange(z.size).reshape(z.shape)
    a, b = i[:-1, :-1].ravel(), i[:-1, 1:].ravel()
    c, d = i[1:, :-1].ravel(), i[1:, 1:].ravel()
    flip = ((np.arange(rows - 1)[:, None] + np.arange(cols - 1)[None, :]) % 2).ravel() == 1
    t1 = np.where(flip[:, None], np.column_stack([a, b, c]), np.column_stack([a, b, d]))
    t2 = np.where(flip[:, None], np.column_stack([b, d, c]), np.column_stack([a, d, c]))
    return TriangleMesh(np.column_stack([xx.ravel(), yy.ravel(), z.ravel()]),
                        np.concatenate([t1, t2]))


def rough_mesh(seed: int = 0) -> TriangleMesh:
    rng = np.random.default_rng(seed)
    z = 0.3 * rng.standard_normal((9, 11)) + 0.05 * np.arange(11)[None, :]
    return grid_mesh(z)


def test_surface_matches_the_per_triangle_reference():
    mesh = rough_mesh()
    res = directional_roughness(mesh, AZIMUTHS)
    f = res.frame
    # the reference plane is the ODR plane of the vertices
    _, _, vt = np.linalg.svd(mesh.vertices - mesh.vertices.mean(0))
    assert abs(abs(vt[2] @ f.normal) - 1) < 1e-12
    ref = surface_reference(mesh.vertices, mesh.faces, f.origin, f.u_axis, f.v_axis, f.normal,
                            AZIMUTHS)
    for j, az in enumerate(AZIMUTHS):
        tmc1, dt, tmax, c = ref[az]
        assert res.delta_t[j] == pytest.approx(dt, rel=1e-9)
        assert res.theta_max[j] == pytest.approx(tmax, rel=1e-9)
        assert res.c[j] == pytest.approx(c, rel=1e-5, abs=1e-7)
        assert res.theta_max_c1[j] == pytest.approx(tmc1, rel=1e-6)
    assert res.area == pytest.approx(sum(
        0.5 * np.linalg.norm(np.cross(*(mesh.vertices[t[1:]] - mesh.vertices[t[0]])))
        for t in mesh.faces))


def test_windows_match_the_per_window_reference():
    mesh = grid_mesh(0.4 * np.random.default_rng(3).standard_normal((15, 15)))
    res = window_roughness(mesh, AZIMUTHS, radius=3.0, step=4.0, min_coverage=0.3)
    assert res.n_windows >= 6
    for w in range(res.n_windows):
        ref, n_tri = window_reference(mesh.vertices, mesh.faces, res.frame, res.centre_uv[w],
                                      3.0, AZIMUTHS)
        assert res.n_triangles[w] == n_tri
        for j, az in enumerate(AZIMUTHS):
            tmc1, dt, tmax, _ = ref[az]
            assert res.delta_t[w, j] == pytest.approx(dt, rel=1e-8)
            assert res.theta_max[w, j] == pytest.approx(tmax, rel=1e-8)
            if math.isnan(tmc1):
                assert np.isnan(res.theta_max_c1[w, j])
            else:
                assert res.theta_max_c1[w, j] == pytest.approx(tmc1, rel=1e-5)
    # the table of --windows-out: one row per window and azimuth, window-major
    table = res.table(per=1.0)
    assert list(table) == ["cx", "cy", "cz", "area", "azimuth_deg", "delta_t", "theta_max_c1"]
    assert table["delta_t"].size == res.n_windows * len(AZIMUTHS)
    np.testing.assert_array_equal(table["azimuth_deg"][:len(AZIMUTHS)], AZIMUTHS)


def sawtooth(up_deg: float, down_deg: float, teeth: int = 6, width: int = 4) -> TriangleMesh:
    """Teeth along x: faces rising at ``up_deg`` then falling at ``down_deg``, each
    tooth 1 high; ridges along y."""
    rise, fall = 1 / math.tan(math.radians(up_deg)), 1 / math.tan(math.radians(down_deg))
    x = [0.0]
    z = [0.0]
    for _ in range(teeth):
        x += [x[-1] + rise, x[-1] + rise + fall]
        z += [1.0, 0.0]
    x, z = np.array(x), np.array(z)
    y = np.arange(width + 1, dtype=float)
    n = x.size
    vert = np.array([[xi, yi, zi] for yi in y for xi, zi in zip(x, z, strict=True)])
    faces = []
    for r in range(width):
        for k in range(n - 1):
            a, b, c, d = r * n + k, r * n + k + 1, (r + 1) * n + k, (r + 1) * n + k + 1
            faces += [[a, b, d], [a, d, c]]
    return TriangleMesh(vert, np.array(faces))


@pytest.mark.parametrize("up, down", [(30.0, 30.0), (20.0, 55.0)])
def test_sawtooth_closed_forms(up, down):
    """Facets rising along +x at ``up``: along t = (cos a, sin a) they rise at
    atan(tan(up) cos a), so that is theta*max, C = 0 (every facing facet has the same
    dip) and theta*max/(C+1) = Delta-T; against the teeth the falling facets face
    the shear at atan(tan(down) |cos a|); along the ridges every facet is flat."""
    mesh = sawtooth(up, down)
    plane = FacePlane(centroid=mesh.vertices.mean(0), normal=np.array([0.0, 0.0, 1.0]))
    az = azimuths(15.0)
    res = directional_roughness(mesh, az, plane=plane)
    for j, a in enumerate(az):
        ca = math.cos(math.radians(a))
        if abs(ca) < 1e-9:
            expected = 0.0
        else:
            expected = math.degrees(math.atan(math.tan(math.radians(up if ca > 0 else down))
                                              * abs(ca)))
        assert res.delta_t[j] == pytest.approx(expected, abs=1e-9)
        assert res.theta_max_c1[j] == pytest.approx(expected, abs=1e-9)
        if abs(ca) > 1e-9:
            assert res.c[j] == 0.0
    # the share facing the shear: the rising facets' area, then the falling ones'
    l_up, l_down = 1 / math.sin(math.radians(up)), 1 / math.sin(math.radians(down))
    assert res.a0[0] == pytest.approx(l_up / (l_up + l_down), rel=1e-12)
    assert res.a0[12] == pytest.approx(l_down / (l_up + l_down), rel=1e-12)


def test_planes_have_no_directional_roughness_in_any_window():
    """A tilted plane: every window's own plane is the plane, so every apparent dip
    is 0, and so are Delta-T and theta*max/(C+1)."""
    yy, xx = np.mgrid[0:12, 0:12].astype(float)
    mesh = grid_mesh(0.4 * xx - 0.2 * yy)
    res = window_roughness(mesh, azimuths(45.0), radius=2.5, step=2.0)
    assert res.n_windows > 10
    np.testing.assert_allclose(res.delta_t, 0.0, atol=1e-9)
    np.testing.assert_allclose(res.theta_max_c1, 0.0, atol=1e-9)


def test_fit_c_recovers_the_exponent_and_the_closed_forms_of_c():
    x = np.tile(np.linspace(0.05, 0.95, 19), (4, 1))
    c_true = np.array([0.0, 0.37, 2.5, 41.0])
    c = fit_c(x, x ** c_true[:, None], np.ones_like(x, dtype=bool))
    np.testing.assert_allclose(c, c_true, rtol=1e-6, atol=1e-9)
    assert np.isnan(fit_c(x[:1], x[:1], np.zeros_like(x[:1], dtype=bool))[0])


def test_apparent_dips_turn_normals_to_the_plane_side():
    up, u, v = np.eye(3)[2], np.eye(3)[0], np.eye(3)[1]
    m = np.array([[-0.5, 0.0, math.sqrt(0.75)]])
    np.testing.assert_allclose(apparent_dips(-m, up, u, v, [0.0]), [[30.0]])


def test_triangulated_cloud_gives_the_mesh_parameters():
    """A cloud triangulated in its plane measures like the mesh it samples: the
    vertices of a grid mesh, triangulated by Delaunay, give the same Delta-T on a
    surface whose squares are planar (so either diagonal makes the same facets)."""
    yy, xx = np.mgrid[0:10, 0:10].astype(float)
    z = 0.3 * np.sin(xx) + 0.1 * yy  # planar within each square? no: use a bilinear-free z
    z = 0.3 * np.abs((xx % 4) - 2)  # a sawtooth along x: squares are planar
    mesh = grid_mesh(z)
    tri = triangulate_cloud(mesh.vertices)
    a = directional_roughness(mesh, AZIMUTHS)
    b = directional_roughness(tri, AZIMUTHS)
    np.testing.assert_allclose(b.delta_t, a.delta_t, atol=1e-9)
    assert tri.n_faces == mesh.n_faces


def test_long_triangles_across_a_hole_are_dropped():
    yy, xx = np.mgrid[0:20, 0:20].astype(float)
    keep = ~((xx > 6) & (xx < 13) & (yy > 6) & (yy < 13))  # a hole 7 spacings wide
    pts = np.column_stack([xx[keep], yy[keep], 0.1 * np.sin(xx[keep])])

    def longest(mesh):
        c = mesh.vertices[mesh.faces][:, :, :2]
        e = c - np.roll(c, 1, axis=1)
        return np.sqrt((e * e).sum(axis=2)).max(axis=1)

    full = triangulate_cloud(pts, max_edge=np.inf)
    kept = triangulate_cloud(pts)  # default: 5 point spacings (the spacing is 1)
    assert longest(full).max() > 7 and longest(kept).max() <= 5
    assert kept.n_faces == int(np.count_nonzero(longest(full) <= 5))
    assert float(facets(kept).areas.sum()) < float(facets(full).areas.sum()) - 20


def test_bad_settings_are_one_line_errors():
    mesh = rough_mesh()
    with pytest.raises(InputError, match="azimuth step"):
        azimuths(0)
    with pytest.raises(InputError, match="dip step"):
        directional_roughness(mesh, [0], dip_step_deg=0)
    with pytest.raises(InputError, match="radius"):
        window_roughness(mesh, [0], radius=-1, step=1)
    with pytest.raises(InputError, match="no window"):
        window_roughness(mesh, [0], radius=0.5, step=1)
    with pytest.raises(InputError, match="line"):
        triangulate_cloud(np.column_stack([np.arange(5.0), np.arange(5.0), np.zeros(5)]))
