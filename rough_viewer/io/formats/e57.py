"""E57 (ASTM E2807), the exchange format of terrestrial laser scanners, read with
pye57 (the Python binding of libE57Format).

A file holds one or more scans (``data3D``), each in its own frame with a pose
(rotation quaternion and translation) into the file's frame. Every scan is read,
its invalid points (``cartesianInvalidState`` != 0) dropped, transformed by its pose
and merged. The cloud keeps intensity (float, as stored), colour (as stored),
``scan_index`` (which scan each point came from) and ``scanner_positions`` (each
pose's translation: the scanner's origin in the file's frame, metres), for later
use such as range and incidence angle. E57 coordinates are metres by the standard.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rough_viewer.io.cloud import PointCloud, finite_cloud
from rough_viewer.io.costs import COSTS
from rough_viewer.memory import require
from rough_viewer.vocabulary import InputError, ProgressFn, foreign_errors

#: Bytes per point at the peak of a read (measured: :data:`rough_viewer.io.estimates.COSTS`).
E57_BYTES_PER_POINT = COSTS["e57"].per_point

_XYZ = ("cartesianX", "cartesianY", "cartesianZ")
_RGB = ("colorRed", "colorGreen", "colorBlue")


def quaternion_matrix(wxyz: np.ndarray) -> np.ndarray:
    """Rotation matrix (3x3) of a quaternion ``(w, x, y, z)`` (normalised first).

    >>> quaternion_matrix(np.array([1.0, 0.0, 0.0, 0.0]))
    array([[1., 0., 0.],
           [0., 1., 0.],
           [0., 0., 1.]])
    """
    w, x, y, z = np.asarray(wxyz, dtype=np.float64) / np.linalg.norm(wxyz)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def read_e57(p: Path, *, progress: ProgressFn | None = None,
             max_points: int | None = None) -> PointCloud:
    """Read every scan of an E57 file into one cloud in the file's frame (metres).

    ``max_points``: the decompression-bomb guard's limit
    (:func:`rough_viewer.io.estimates.check_plausible`).

    Raises
    ------
    InputError
        pye57 not installed, an unreadable or damaged file (libE57Format's error, in
        one line), no scans, a scan without Cartesian coordinates (spherical only),
        more points than the file can hold, or more than fit in memory.
    """
    try:
        import pye57
    except ImportError:
        raise InputError(f"reading {p} needs pye57 (pip install pye57)") from None
    with foreign_errors(f"cannot read {p} as E57"):  # libE57Format raises its own types
        return _read_e57(pye57.E57(str(p)), p, progress, max_points)


def _read_e57(e57, p: Path, progress: ProgressFn | None, max_points: int | None) -> PointCloud:
    from rough_viewer.io.estimates import check_plausible

    try:
        n_scans = int(e57.scan_count)
        if n_scans == 0:
            raise InputError(f"no scans in {p}")
        headers = [e57.get_header(i) for i in range(n_scans)]
        for i, h in enumerate(headers):
            if not all(f in h.point_fields for f in _XYZ):
                raise InputError(
                    f"scan {i} of {p} has no Cartesian coordinates (only "
                    f"{', '.join(sorted(h.point_fields)) or 'nothing'}); export it with x, y, z"
                )
        counts = [int(h.point_count) for h in headers]
        total = sum(counts)
        check_plausible(p, total, size=p.stat().st_size, kind="e57", max_points=max_points,
                        label="E57")
        require(total * E57_BYTES_PER_POINT, f"reading {total:,} points from {p}",
                hint="use a smaller file or a machine with more memory")
        has_int = all("intensity" in h.point_fields for h in headers)
        has_rgb = all(all(c in h.point_fields for c in _RGB) for h in headers)
        parts_xyz: list[np.ndarray] = []
        parts_int: list[np.ndarray] = []
        parts_rgb: list[np.ndarray] = []
        parts_idx: list[np.ndarray] = []
        positions = np.zeros((n_scans, 3))
        done = 0
        if progress:
            progress(0, total)
        for i, h in enumerate(headers):
            data = e57.read_scan(i, intensity=has_int, colors=has_rgb, transform=False,
                                 ignore_missing_fields=True)
            local = np.column_stack([np.asarray(data[c], dtype=np.float64) for c in _XYZ])
            if h.has_pose():
                rot = quaternion_matrix(np.asarray(h.rotation, dtype=np.float64))
                shift = np.asarray(h.translation, dtype=np.float64)
                local = local @ rot.T + shift
                positions[i] = shift
            parts_xyz.append(local)
            parts_idx.append(np.full(local.shape[0], i, dtype=np.int32))
            if has_int:
                parts_int.append(np.asarray(data["intensity"]))
            if has_rgb:
                parts_rgb.append(np.column_stack([np.asarray(data[c]) for c in _RGB]))
            done += counts[i]
            if progress:
                progress(done, total)
    finally:
        e57.close()
    xyz = np.concatenate(parts_xyz)
    del parts_xyz
    return finite_cloud(
        np.ascontiguousarray(xyz[:, 0]), np.ascontiguousarray(xyz[:, 1]),
        np.ascontiguousarray(xyz[:, 2]),
        np.concatenate(parts_int) if has_int else None, p,
        rgb=np.concatenate(parts_rgb) if has_rgb else None,
        scan_index=np.concatenate(parts_idx),
        scanner_positions=positions,
    )
