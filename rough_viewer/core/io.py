"""Reading point clouds from files, and writing LAS/LAZ.

Supported inputs (by file extension):

- ``.las``, ``.laz``: laspy, read in chunks; LAZ decoded with the parallel lazrs
  backend and its decoded coordinates cached (see :func:`cache_dir`), so a second
  open is near-instant. Intensity is kept.
- ``.xyz``, ``.txt``, ``.csv``, ``.pts``: whitespace- or comma-separated ``x y z``,
  extra columns ignored, an optional header line.
- ``.npy``: an (N, 3) (or wider: the first three columns) numeric array.
- ``.ply``: ASCII or binary (either endianness) vertex ``x``, ``y``, ``z``.
- ``.stl``: ASCII or binary; the mesh's vertices, each once.

Rows with NaN or infinite coordinates are dropped and counted
(:attr:`PointCloud.dropped_nonfinite`). Every problem raises
:class:`rough_viewer.errors.InputError` with the file's name.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
import re
import shutil
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rough_viewer.errors import InputError
from rough_viewer.progress import ProgressFn

TEXT_SUFFIXES = (".xyz", ".txt", ".csv", ".pts")
SUPPORTED_SUFFIXES = (".las", ".laz", *TEXT_SUFFIXES, ".npy", ".ply", ".stl")
#: Points per chunk when reading LAS/LAZ.
LAS_CHUNK = 2_000_000


@dataclass(frozen=True)
class PointCloud:
    """Points as three float64 columns (structure of arrays), metres, the file's frame."""

    x: np.ndarray
    """(N,) float64 x, metres."""
    y: np.ndarray
    """(N,) float64 y, metres."""
    z: np.ndarray
    """(N,) float64 z, metres."""
    intensity: np.ndarray | None = None
    """(N,) intensity as stored in the file, or None."""
    source: str = ""
    """Path of the file read, or ``""`` for an in-memory cloud."""
    dropped_nonfinite: int = 0
    """Rows dropped because a coordinate was NaN or infinite."""

    @property
    def n(self) -> int:
        """Number of points."""
        return int(self.x.shape[0])

    def xyz(self) -> np.ndarray:
        """(N, 3) float64 array of the coordinates (a new array)."""
        return np.column_stack([self.x, self.y, self.z])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounding box ``(min, max)``, each (3,), metres."""
        lo = np.array([self.x.min(), self.y.min(), self.z.min()])
        hi = np.array([self.x.max(), self.y.max(), self.z.max()])
        return lo, hi

    @classmethod
    def from_xyz(
        cls, xyz: np.ndarray, intensity: np.ndarray | None = None, source: str = ""
    ) -> PointCloud:
        """A cloud from an (N, 3) array (copied into contiguous float64 columns)."""
        arr = np.asarray(xyz, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] < 3:
            raise ValueError("xyz must be an (N, 3) array")
        return cls(
            x=np.ascontiguousarray(arr[:, 0]),
            y=np.ascontiguousarray(arr[:, 1]),
            z=np.ascontiguousarray(arr[:, 2]),
            intensity=None if intensity is None else np.asarray(intensity),
            source=source,
        )

    def subset(self, which: np.ndarray) -> PointCloud:
        """The points selected by a boolean mask or an index array."""
        return PointCloud(
            x=self.x[which],
            y=self.y[which],
            z=self.z[which],
            intensity=None if self.intensity is None else self.intensity[which],
            source=self.source,
            dropped_nonfinite=self.dropped_nonfinite,
        )


def _finite_cloud(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, intensity: np.ndarray | None, path: Path
) -> PointCloud:
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(z)
    dropped = int(ok.size - np.count_nonzero(ok))
    if dropped:
        x, y, z = x[ok], y[ok], z[ok]
        intensity = None if intensity is None else intensity[ok]
    n = int(x.shape[0])
    if n == 0:
        extra = f" ({dropped} rows with NaN or infinite coordinates dropped)" if dropped else ""
        raise InputError(f"no points in {path}{extra}")
    if n < 3:
        raise InputError(f"only {n} point(s) in {path}; at least 3 are needed")
    return PointCloud(
        x=np.ascontiguousarray(x, dtype=np.float64),
        y=np.ascontiguousarray(y, dtype=np.float64),
        z=np.ascontiguousarray(z, dtype=np.float64),
        intensity=intensity,
        source=str(path),
        dropped_nonfinite=dropped,
    )


def load_points(
    path: str | os.PathLike[str], *, progress: ProgressFn | None = None, cache: bool = True
) -> PointCloud:
    """Read a point cloud file.

    Parameters
    ----------
    path : path-like
        A ``.las .laz .xyz .txt .csv .pts .npy .ply .stl`` file.
    progress : callable, optional
        ``progress(done, total)`` in points, for LAS/LAZ files.
    cache : bool
        Use (and fill) the decoded-coordinate cache for LAZ files.

    Returns
    -------
    PointCloud

    Raises
    ------
    InputError
        Missing or unreadable file, unknown extension, malformed content, fewer than
        3 finite points.
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in SUPPORTED_SUFFIXES:
        raise InputError(
            f"unknown file type {p.suffix or '(none)'!r} for {p}; "
            f"supported: {' '.join(SUPPORTED_SUFFIXES)}"
        )
    if not p.exists():
        raise InputError(f"file not found: {p}")
    if not p.is_file():
        raise InputError(f"not a file: {p}")
    if not os.access(p, os.R_OK):
        raise InputError(f"cannot read {p}: permission denied")
    try:
        if suffix in (".las", ".laz"):
            return _read_las(p, progress=progress, cache=cache and suffix == ".laz")
        if suffix in TEXT_SUFFIXES:
            return _read_text(p)
        if suffix == ".npy":
            return _read_npy(p)
        if suffix == ".ply":
            return _read_ply(p)
        return _read_stl(p)
    except InputError:
        raise
    except MemoryError:
        raise InputError(f"not enough memory to read {p}") from None
    except (OSError, ValueError, EOFError, KeyError, IndexError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"cannot read {p}: {msg}") from None
    except Exception as exc:  # laspy raises its own error types
        if type(exc).__module__.startswith("laspy") or "Laz" in type(exc).__name__:
            msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise InputError(f"cannot read {p}: {msg}") from None
        raise


# ----------------------------------------------------------------------------- LAS/LAZ


def _laz_backend():
    import laspy

    available = laspy.LazBackend.detect_available()
    for b in (laspy.LazBackend.LazrsParallel, laspy.LazBackend.Lazrs):
        if b in available:
            return b
    return None


def cache_dir() -> Path:
    """Folder of the LAZ decode cache: ``$ROUGH_VIEWER_CACHE`` or
    ``$XDG_CACHE_HOME/rough_viewer`` (default ``~/.cache/rough_viewer``)."""
    env = os.environ.get("ROUGH_VIEWER_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "rough_viewer"


def _cache_key(p: Path) -> str:
    st = p.stat()
    ident = f"{p.resolve()}|{st.st_size}|{st.st_mtime_ns}|v1"
    return hashlib.sha1(ident.encode()).hexdigest()[:20]


def _cache_read(p: Path) -> PointCloud | None:
    folder = cache_dir() / _cache_key(p)
    try:
        meta = json.loads((folder / "meta.json").read_text())
        cols = [np.load(folder / f"{c}.npy") for c in "xyz"]
        inten = np.load(folder / "intensity.npy") if meta.get("intensity") else None
    except (OSError, ValueError):
        return None
    return PointCloud(
        x=cols[0], y=cols[1], z=cols[2], intensity=inten, source=str(p),
        dropped_nonfinite=int(meta.get("dropped", 0)),
    )


def _cache_write(p: Path, cloud: PointCloud) -> None:
    root = cache_dir()
    final = root / _cache_key(p)
    try:
        root.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=".part-", dir=root))
        for c in "xyz":
            np.save(tmp / f"{c}.npy", getattr(cloud, c))
        if cloud.intensity is not None:
            np.save(tmp / "intensity.npy", cloud.intensity)
        meta = {"source": str(p), "intensity": cloud.intensity is not None,
                "dropped": cloud.dropped_nonfinite}
        (tmp / "meta.json").write_text(json.dumps(meta))
        try:
            os.replace(tmp, final)
        except OSError:
            shutil.rmtree(tmp, ignore_errors=True)
    except OSError:
        pass  # a cache we cannot write is no error


def _read_las(p: Path, *, progress: ProgressFn | None, cache: bool) -> PointCloud:
    import laspy

    if cache:
        cached = _cache_read(p)
        if cached is not None:
            if progress:
                progress(cached.n, cached.n)
            return cached
    sel = laspy.DecompressionSelection.base() | laspy.DecompressionSelection.INTENSITY
    with laspy.open(p, laz_backend=_laz_backend(), decompression_selection=sel) as reader:
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
    cloud = _finite_cloud(x, y, z, inten, p)
    if cache:
        _cache_write(p, cloud)
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
    las.write(str(p), do_compress=p.suffix.lower() == ".laz", laz_backend=_laz_backend())


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
        with laspy.open(p, laz_backend=_laz_backend()) as reader:
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
    cloud = _finite_cloud(x, y, z, np.asarray(las.intensity), p)
    return cloud, {name: np.asarray(las[name])[ok] for name in names}


def read_las_extra(path: str | os.PathLike[str], name: str) -> np.ndarray:
    """Read one extra dimension (e.g. ``"truth"``) from a LAS/LAZ file."""
    return load_las_with_extra(path, (name,))[1][name]


# ----------------------------------------------------------------------------- text

_NUM = re.compile(r"^\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*$")


def _read_text(p: Path) -> PointCloud:
    with open(p, encoding="utf-8", errors="replace") as fh:
        first = ""
        for line in fh:
            if line.strip():
                first = line
                break
    if not first:
        raise InputError(f"no points in {p}")
    delim = "," if "," in first else None
    fields = [f for f in (first.split(",") if delim else first.split())]
    header = not all(_NUM.match(f) for f in fields[:3]) or len(fields) < 3
    if len(fields) < 3:
        raise InputError(f"expected at least 3 columns (x y z) in {p}, found {len(fields)}")
    try:
        data = np.loadtxt(
            p, delimiter=delim, usecols=(0, 1, 2), skiprows=1 if header else 0,
            dtype=np.float64, comments="#", ndmin=2,
        )
    except ValueError as exc:
        msg = str(exc).splitlines()[0]
        raise InputError(f"cannot parse {p} as x y z columns: {msg}") from None
    if data.shape[0] == 0:
        raise InputError(f"no points in {p}")
    return _finite_cloud(data[:, 0].copy(), data[:, 1].copy(), data[:, 2].copy(), None, p)


# ----------------------------------------------------------------------------- npy


def _read_npy(p: Path) -> PointCloud:
    try:
        arr = np.load(p, allow_pickle=False)
    except ValueError as exc:
        raise InputError(f"cannot read {p} as a numpy array: {exc}") from None
    if arr.dtype.names and all(k in arr.dtype.names for k in "xyz"):
        cols = [np.asarray(arr[k], dtype=np.float64) for k in "xyz"]
        return _finite_cloud(*cols, None, p)
    if arr.ndim != 2 or arr.shape[1] < 3 or not np.issubdtype(arr.dtype, np.number):
        raise InputError(f"expected an (N, 3) numeric array in {p}, got shape {arr.shape}")
    arr = arr.astype(np.float64, copy=False)
    return _finite_cloud(arr[:, 0].copy(), arr[:, 1].copy(), arr[:, 2].copy(), None, p)


# ----------------------------------------------------------------------------- ply

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def _read_ply(p: Path) -> PointCloud:
    with open(p, "rb") as fh:
        if fh.readline().strip() != b"ply":
            raise InputError(f"not a PLY file (no 'ply' magic line): {p}")
        fmt = None
        elements: list[tuple[str, int, list[tuple[str, str | None, str]]]] = []
        while True:
            raw = fh.readline()
            if not raw:
                raise InputError(f"PLY header has no end_header: {p}")
            parts = raw.decode("ascii", errors="replace").split()
            if not parts or parts[0] in ("comment", "obj_info"):
                continue
            if parts[0] == "format":
                fmt = parts[1]
            elif parts[0] == "element":
                elements.append((parts[1], int(parts[2]), []))
            elif parts[0] == "property":
                if not elements:
                    raise InputError(f"PLY property before any element: {p}")
                if parts[1] == "list":
                    elements[-1][2].append((parts[4], parts[2], parts[3]))
                else:
                    elements[-1][2].append((parts[2], None, parts[1]))
            elif parts[0] == "end_header":
                break
        if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
            raise InputError(f"unsupported PLY format {fmt!r} in {p}")
        names = [e[0] for e in elements]
        if "vertex" not in names:
            raise InputError(f"PLY file has no vertex element: {p}")
        vi = names.index("vertex")
        _, n_vert, props = elements[vi]
        pnames = [q[0] for q in props]
        if not all(k in pnames for k in "xyz"):
            raise InputError(f"PLY vertex element lacks x, y, z properties: {p}")
        if fmt == "ascii":
            skip = sum(e[1] for e in elements[:vi])
            if any(q[1] is not None for q in props):
                raise InputError(f"PLY vertex element with list properties is not supported: {p}")
            for _ in range(skip):
                fh.readline()
            cols = tuple(pnames.index(k) for k in "xyz")
            data = np.loadtxt(fh, usecols=cols, max_rows=n_vert, ndmin=2, dtype=np.float64)
            if data.shape[0] != n_vert:
                raise InputError(f"PLY file is truncated: {data.shape[0]} of {n_vert} vertices in {p}")
        else:
            end = "<" if fmt == "binary_little_endian" else ">"
            for name, count, eprops in elements[:vi]:
                if any(q[1] is not None for q in eprops):
                    raise InputError(
                        f"PLY element {name!r} with list properties before the vertices is not supported: {p}"
                    )
                fh.seek(count * sum(np.dtype(_PLY_TYPES[q[2]]).itemsize for q in eprops), 1)
            if any(q[1] is not None for q in props):
                raise InputError(f"PLY vertex element with list properties is not supported: {p}")
            try:
                dt = np.dtype([(q[0], end + _PLY_TYPES[q[2]]) for q in props])
            except KeyError as exc:
                raise InputError(f"unknown PLY property type {exc} in {p}") from None
            buf = fh.read(dt.itemsize * n_vert)
            if len(buf) < dt.itemsize * n_vert:
                raise InputError(f"PLY file is truncated: {p}")
            rec = np.frombuffer(buf, dtype=dt, count=n_vert)
            data = np.column_stack([rec[k].astype(np.float64) for k in "xyz"])
    return _finite_cloud(data[:, 0].copy(), data[:, 1].copy(), data[:, 2].copy(), None, p)


# ----------------------------------------------------------------------------- stl

_STL_DTYPE = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])


def _read_stl(p: Path) -> PointCloud:
    size = p.stat().st_size
    with open(p, "rb") as fh:
        head = fh.read(84)
    binary = False
    if len(head) >= 84:
        n_tri = int(np.frombuffer(head[80:84], dtype="<u4")[0])
        binary = size == 84 + 50 * n_tri
    if binary:
        tri = np.fromfile(p, dtype=_STL_DTYPE, offset=84, count=n_tri)
        verts = tri["v"].reshape(-1, 3).astype(np.float64)
    else:
        if not head.lstrip().lower().startswith(b"solid"):
            raise InputError(f"not an STL file (neither binary nor ASCII 'solid'): {p}")
        text = p.read_text(encoding="ascii", errors="replace")
        tokens = text.split()
        arr = np.array(tokens, dtype=object)
        at = np.flatnonzero(arr == "vertex")
        if at.size == 0:
            raise InputError(f"no vertices in {p}")
        if at[-1] + 3 >= arr.size:
            raise InputError(f"STL file is truncated: {p}")
        try:
            verts = np.array(
                [arr[at + 1], arr[at + 2], arr[at + 3]], dtype=np.float64
            ).T
        except ValueError:
            raise InputError(f"malformed vertex line in {p}") from None
    if verts.shape[0] == 0:
        raise InputError(f"no points in {p}")
    verts = verts[np.all(np.isfinite(verts), axis=1)] if not np.all(np.isfinite(verts)) else verts
    uniq = np.unique(verts, axis=0)
    return _finite_cloud(uniq[:, 0].copy(), uniq[:, 1].copy(), uniq[:, 2].copy(), None, p)
