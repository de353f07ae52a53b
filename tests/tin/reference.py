"""A slow, obviously correct reference for the TIN roughness parameters: one triangle
at a time, apparent dips from each triangle's plane solved through its corners
(never from its normal), areas by Heron's formula, C by brute force over a dense
grid refined by scipy's bounded scalar minimiser (Grasselli 2001; Tatone and Grasselli 2009; Babanouri and Karami Nasab 2017).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize_scalar


def heron(p0, p1, p2) -> float:
    a, b, c = (float(np.linalg.norm(q - r)) for q, r in ((p0, p1), (p1, p2), (p2, p0)))
    s = 0.5 * (a + b + c)
    return math.sqrt(max(s * (s - a) * (s - b) * (s - c), 0.0))


def apparent_dip(corners, origin, u, v, n, azimuth_deg) -> float:
    """Slope angle along cos(a) u + sin(a) v of the plane h = A s + B t + C through
    the corners, in coordinates (s, t, h) of the frame (u, v, n), degrees."""
    rel = np.asarray(corners, dtype=float) - origin
    st = np.column_stack([rel @ u, rel @ v, np.ones(3)])
    a_, b_, _ = np.linalg.solve(st, rel @ n)
    az = math.radians(azimuth_deg)
    return math.degrees(math.atan(a_ * math.cos(az) + b_ * math.sin(az)))


def grasselli(dips, areas, dip_step) -> tuple[float, float, float]:
    """(theta_max, C, theta_max / (C + 1)) of one surface in one direction."""
    total = sum(areas)
    facing = [(d, a) for d, a in zip(dips, areas, strict=True) if d >= 0]
    if not facing:
        return math.nan, math.nan, math.nan
    tmax = max(d for d, _ in facing)
    a0 = sum(a for _, a in facing) / total
    xs, ys = [], []
    k = 1
    while k * dip_step < tmax:
        th = k * dip_step
        xs.append(1 - th / tmax)
        ys.append(sum(a for d, a in facing if d >= th) / total / a0)
        k += 1
    if not xs:
        return tmax, math.nan, math.nan

    def sse(c):
        return sum((y - x**c) ** 2 for x, y in zip(xs, ys, strict=True))

    # brute force over a dense grid of C, then a bounded search around the best one
    grid = [0.0] + [10 ** (k / 100) for k in range(-400, 401)]
    values = [sse(c) for c in grid]
    j = min(range(len(grid)), key=values.__getitem__)
    lo, hi = grid[max(j - 1, 0)], grid[min(j + 1, len(grid) - 1)]
    best = minimize_scalar(sse, bounds=(lo, hi), method="bounded",
                           options={"xatol": 1e-14, "maxiter": 500})
    c = float(best.x) if best.fun < values[j] else grid[j]
    return tmax, c, tmax / (c + 1)


def delta_t(dips, areas) -> float:
    pairs = [(d, a) for d, a in zip(dips, areas, strict=True) if d >= 0]
    return sum(d * a for d, a in pairs) / sum(a for _, a in pairs) if pairs else math.nan


def surface_reference(vertices, faces, origin, u, v, n, azimuths, dip_step=1.0):
    """{azimuth: (theta_max_c1, delta_t, theta_max, c)} of the triangles ``faces``."""
    out = {}
    areas = [heron(*vertices[f]) for f in faces]
    for az in azimuths:
        dips = [apparent_dip(vertices[f], origin, u, v, n, az) for f in faces]
        keep = [i for i, a in enumerate(areas) if a > 0]
        d = [dips[i] for i in keep]
        a = [areas[i] for i in keep]
        tmax, c, tmc1 = grasselli(d, a, dip_step)
        out[az] = (tmc1, delta_t(d, a), tmax, c)
    return out


def window_reference(vertices, faces, frame, centre_uv, radius, azimuths, dip_step=1.0):
    """The same for one window: triangles whose corners lie within ``radius`` of the
    centre in the face plane, measured in the ODR plane of their distinct corners
    (normal on the face normal's side, u the face's u projected, v = n x u)."""
    inside = []
    for f in faces:
        ok = True
        for i in f:
            rel = vertices[i] - frame.origin
            du = rel @ frame.u_axis - centre_uv[0]
            dv = rel @ frame.v_axis - centre_uv[1]
            ok = ok and math.hypot(du, dv) <= radius
        if ok:
            inside.append(f)
    corners = vertices[sorted({int(i) for f in inside for i in f})]
    centroid = corners.mean(axis=0)
    _, _, vt = np.linalg.svd(corners - centroid)
    n = vt[2] if vt[2] @ frame.normal >= 0 else -vt[2]
    u = frame.u_axis - (frame.u_axis @ n) * n
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    if v @ frame.v_axis < 0:
        v = -v
    return surface_reference(vertices, np.array(inside), centroid, u, v, n, azimuths,
                             dip_step), len(inside)
