"""LAS/LAZ: reading points in chunks (LAZ through the parallel lazrs backend, with the
decode cache) and writing clouds with extra dimensions."""

from __future__ import annotations

import datetime as _dt
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from rough_viewer.io.cache import cache_read, cache_write
from rough_viewer.io.cloud import PointCloud, finite_cloud
from rough_viewer.vocabulary import InputError, ProgressFn

#: Points per chunk when reading LAS/LAZ.
LAS_CHUNK = 2_000_000


def laz_backend():
    import laspy

    available = laspy.LazBackend.detect_available()
    for b in (laspy.LazBackend.LazrsParallel, laspy.LazBackend.Lazrs):
        if b in available:
            return b
    return None


def read_las(p: Path, *, progress: ProgressFn | None, cache: bool) -> PointCloud:
    import laspy

    if cache:
        cached = cache_read(p)
        if cached is not None:
            if progress:
                progress(cached.n, cached.n)
            return cached
    sel = laspy.DecompressionSelection.base() | laspy.DecompressionSelection.INTENSITY
    with laspy.open(p, laz_backend=laz_backend(), decompression_selection=sel) as reader:
        hdr = reader.header
        n = int(hdr.point_count)
        scale = np.asarray(hdr.scales, dtype=np.float64)
        offset = np.asarray(hdr.offsets, dtype=np.float64)
        x = np.empty(n)
        y = np.empty(n)
        z = np.empty(n)
        inten = np.empty(n, dtype=np.uint16)
        done = 0
        if progress:
            progress(0, n)
        for chunk in reader.chunk_iterator(LAS_CHUNK):
            m = len(chunk)
            sl = slice(done, done + m)
            np.multiply(chunk.X, scale[0], out=x[sl])
            x[sl] += offset[0]
            np.multiply(chunk.Y, scale[1], out=y[sl])
            y[sl] += offset[1]
            np.multiply(chunk.Z, scale[2], out=z[sl])
            z[sl] += offset[2]
            inten[sl] = chunk.intensity
            done += m
            if progress:
                progress(done, n)
        if done < n:
            x, y, z, inten = x[:done], y[:done], z[:done], inten[:done]
    cloud = finite_cloud(x, y, z, inten, p)
    if cache:
        cache_write(p, cloud)
    return cloud


def write_las(
    path: str | os.PathLike[str],
    cloud: PointCloud,
    *,
    scale: float = 1e-4,
    extra: Mapping[str, np.ndarray] | None = None,
    creation_date: _dt.date | None = None,
) -> None:
    """Write a cloud as LAS (``.las``) or LAZ (``.laz``, lazrs).

    Parameters
    ----------
    path : path-like
        Output file; its suffix chooses compression.
    cloud : PointCloud
        Points (intensity written when present).
    scale : float
        Coordinate resolution, metres (LAS stores scaled integers).
    extra : mapping, optional
        Extra per-point dimensions, name -> (N,) array (e.g. ground-truth labels).
    creation_date : datetime.date, optional
        Header date; default 2000-01-01 so that the same points give the same bytes.
    """
    import laspy

    hdr = laspy.LasHeader(point_format=1, version="1.2")
    lo, _ = cloud.bounds()
    hdr.offsets = np.floor(lo)
    hdr.scales = np.array([scale, scale, scale])
    hdr.creation_date = creation_date or _dt.date(2000, 1, 1)
    hdr.generating_software = "rough_viewer"
    extra = dict(extra or {})
    if extra:
        hdr.add_extra_dims(
            [laspy.ExtraBytesParams(name=k, type=np.asarray(v).dtype) for k, v in extra.items()]
        )
    las = laspy.LasData(hdr)
    las.x = cloud.x
    las.y = cloud.y
    las.z = cloud.z
    if cloud.intensity is not None:
        las.intensity = np.clip(np.asarray(cloud.intensity), 0, 65535).astype(np.uint16)
    for k, v in extra.items():
        las[k] = np.asarray(v)
    p = Path(path)
    las.write(str(p), do_compress=p.suffix.lower() == ".laz", laz_backend=laz_backend())


def load_las_with_extra(
    path: str | os.PathLike[str], names: tuple[str, ...]
) -> tuple[PointCloud, dict[str, np.ndarray]]:
    """Read a LAS/LAZ file's points and some of its extra dimensions in one decode.

    Parameters
    ----------
    path : path-like
        A ``.las`` or ``.laz`` file.
    names : tuple of str
        Extra dimensions to return (e.g. ``("truth",)``).

    Returns
    -------
    PointCloud, dict
        The points (metres, with intensity) and name -> (N,) array, row-aligned.
    """
    import laspy

    p = Path(path)
    try:
        with laspy.open(p, laz_backend=laz_backend()) as reader:
            las = reader.read()
    except Exception as exc:  # laspy and lazrs raise their own types
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"cannot read {p}: {msg}") from None
    present = list(las.point_format.extra_dimension_names)
    for name in names:
        if name not in present:
            raise InputError(f"no extra dimension {name!r} in {p}")
    x, y, z = (np.asarray(c, dtype=np.float64) for c in (las.x, las.y, las.z))
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(z)
    cloud = finite_cloud(x, y, z, np.asarray(las.intensity), p)
    return cloud, {name: np.asarray(las[name])[ok] for name in names}


def read_las_extra(path: str | os.PathLike[str], name: str) -> np.ndarray:
    """Read one extra dimension (e.g. ``"truth"``) from a LAS/LAZ file."""
    return load_las_with_extra(path, (name,))[1][name]


