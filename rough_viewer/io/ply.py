"""PLY point files: ASCII or binary (either byte order), vertex ``x``, ``y``, ``z``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rough_viewer.io.cloud import PointCloud, finite_cloud
from rough_viewer.vocabulary import InputError

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def read_ply(p: Path) -> PointCloud:
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
    return finite_cloud(data[:, 0].copy(), data[:, 1].copy(), data[:, 2].copy(), None, p)


