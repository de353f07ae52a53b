"""The coordinate reference system (CRS) a point file declares: its name, EPSG code
and linear unit, read without pyproj.

LAS/LAZ files declare their CRS in variable-length records (VLRs, or extended VLRs
in LAS 1.4) of user id ``LASF_Projection``: an OGC WKT string (record 2112) or the
GeoTIFF keys (records 34735 directory, 34736 doubles, 34737 text). GeoTIFF rasters
carry the same keys in TIFF tags; an ESRI ASCII grid may have a ``.prj`` file (WKT)
beside it. E57 coordinates are metres by the standard. Text, NPY, PLY and STL files
carry no CRS.

>>> info = parse_wkt_crs('PROJCS["NAD83 / UTM zone 11N",GEOGCS["NAD83",'
...     'UNIT["degree",0.0174532925199433]],UNIT["metre",1],AUTHORITY["EPSG","26911"]]')
>>> info.unit, info.epsg
('m', 26911)
"""

from __future__ import annotations

import os
import re
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rough_viewer.io.cloud import check_input_file
from rough_viewer.vocabulary import CrsUnit, InputError, foreign_errors

#: EPSG unit-of-measure codes (GeoTIFF ProjLinearUnitsGeoKey) -> unit.
EPSG_UNITS: dict[int, CrsUnit] = {9001: "m", 9002: "ft", 9003: "us-ft"}

#: GeoTIFF keys read here.
GT_MODEL_TYPE = 1024          # 1 projected, 2 geographic, 3 geocentric
GT_CITATION = 1026
GEOGRAPHIC_TYPE = 2048
PROJECTED_CS_TYPE = 3072
PCS_CITATION = 3073
PROJ_LINEAR_UNITS = 3076
VERTICAL_CS_TYPE = 4096
VERTICAL_UNITS = 4099

_USER_DEFINED = 32767


@dataclass(frozen=True)
class CrsInfo:
    """What a file says about its coordinate reference system; None where it says nothing."""

    description: str | None = None
    """WKT string, or a readable name (GeoTIFF citation or ``"EPSG:26911"``)."""
    unit: CrsUnit | None = None
    """Linear unit of the horizontal coordinates, or None when not declared or angular."""
    epsg: int | None = None
    """EPSG code of the (horizontal) CRS, where the file gives one."""
    vertical_unit: CrsUnit | None = None
    """Linear unit of z where declared separately (GeoTIFF VerticalUnitsGeoKey, WKT
    vertical CRS)."""
    geographic: bool = False
    """True when the coordinates are longitude/latitude (degrees): no roughness in
    metres can be computed from them without a projection."""
    source: str = ""
    """Where it came from: ``"wkt"``, ``"geotiff"``, ``"e57"`` or ``""`` (nothing)."""


NO_CRS = CrsInfo()


def read_crs(path: str | os.PathLike[str]) -> CrsInfo:
    """The CRS a point file declares (header only; no points are decoded).

    Parameters
    ----------
    path : path-like
        Any file :func:`rough_viewer.io.load.load_points` reads.

    Returns
    -------
    CrsInfo
        All fields None for formats without a CRS or files that declare none. A WKT
        record wins over GeoTIFF keys when a file has both (LAS 1.4 says so).

    Raises
    ------
    InputError
        A LAS/LAZ file whose header cannot be read.
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix in (".las", ".laz"):
        return _las_crs(p)
    if suffix == ".e57":
        return CrsInfo(description=None, unit="m", source="e57")
    if suffix in (".tif", ".tiff"):
        return _geotiff_crs(p)
    if suffix == ".asc":
        return _prj_crs(p)
    return NO_CRS


def _geotiff_crs(p: Path) -> CrsInfo:
    """The GeoKeys of a GeoTIFF raster (the same keys a LAS file may carry)."""
    from rough_viewer.io.dem import GEO_KEY_DIRECTORY, geokey_bytes, geotiff_tags

    check_input_file(p)
    with foreign_errors(f"cannot read the tags of {p}"):
        tags = geotiff_tags(p)
    if GEO_KEY_DIRECTORY not in tags:
        return NO_CRS
    return parse_geotiff_keys(*geokey_bytes(tags))


def _prj_crs(p: Path) -> CrsInfo:
    """The WKT of the ``.prj`` file beside an ESRI ASCII grid, if any."""
    from rough_viewer.io.dem import prj_beside

    prj = prj_beside(p)
    if prj is None:
        return NO_CRS
    with foreign_errors(f"cannot read {prj}"):
        size = prj.stat().st_size
        if size > MAX_CRS_RECORD_BYTES:
            raise InputError(f"{prj} is {size:,} bytes, over the {MAX_CRS_RECORD_BYTES:,} a "
                             "CRS may hold: not a .prj file, or a damaged one")
        text = prj.read_text(encoding="utf-8", errors="replace").strip()
    return parse_wkt_crs(text) if text else NO_CRS


#: Most VLRs and EVLRs together a LAS header may declare for its CRS to be read (real
#: files hold a handful; a file of a million empty VLRs took 272 MB and 7.7 s through
#: laspy in the server's process).
MAX_LAS_RECORDS = 10_000
#: Longest CRS record read, bytes: an EPSG WKT2 is a few kB, and parsing costs about 240
#: bytes of memory a byte of WKT (20 MiB of ``[`` took a process to 5 GB).
MAX_CRS_RECORD_BYTES = 128 << 10
#: The CRS records of a LAS file (user id ``LASF_Projection``).
_CRS_RECORDS = (2112, 34735, 34736, 34737)


def las_crs_records(p: Path) -> dict[int, bytes]:
    """The CRS records of a LAS/LAZ file by record id, read from its own header with
    stated bounds (no library: only the record headers and the CRS payloads, each at
    most :data:`MAX_CRS_RECORD_BYTES`, of at most :data:`MAX_LAS_RECORDS` records).

    Raises
    ------
    InputError
        Not a LAS file, a truncated record table, or a table or CRS record over its
        bound.
    """
    from rough_viewer.io.las import check_las_layout

    check_las_layout(p)  # the signature, header size, offsets and table sizes fit the file
    out: dict[int, bytes] = {}
    with open(p, "rb") as fh:
        head = fh.read(375)
        version = (head[24], head[25])
        header_size, = struct.unpack_from("<H", head, 94)
        n_vlrs, = struct.unpack_from("<I", head, 100)
        evlr_start, n_evlrs = 0, 0
        if version >= (1, 4) and len(head) >= 247:
            evlr_start, = struct.unpack_from("<Q", head, 235)
            n_evlrs, = struct.unpack_from("<I", head, 243)
        if n_vlrs + n_evlrs > MAX_LAS_RECORDS:
            raise InputError(f"{p}: its header declares {n_vlrs:,} VLRs and {n_evlrs:,} "
                             f"EVLRs, over the {MAX_LAS_RECORDS:,} read: a damaged file")
        size = os.fstat(fh.fileno()).st_size

        def table(pos: int, count: int, record_header: int, length_format: str, kind: str
                  ) -> None:
            for _ in range(count):
                fh.seek(pos)
                h = fh.read(record_header)
                if len(h) < record_header:
                    raise InputError(f"cannot read the header of {p}: its {kind} table ends "
                                     "early (a truncated file)")
                user = h[2:18].split(b"\0", 1)[0]
                rid, = struct.unpack_from("<H", h, 18)
                length, = struct.unpack_from(length_format, h, 20)
                if user == b"LASF_Projection" and rid in _CRS_RECORDS:
                    if length > MAX_CRS_RECORD_BYTES:
                        raise InputError(f"{p}: its CRS record (LASF_Projection {rid}) is "
                                         f"{length:,} bytes, over the {MAX_CRS_RECORD_BYTES:,} "
                                         "a CRS may hold: a damaged file")
                    out[rid] = fh.read(length)
                pos += record_header + length
                if pos > size:
                    raise InputError(f"cannot read the header of {p}: a {kind} reaches past "
                                     "the end of the file")

        table(header_size, n_vlrs, 54, "<H", "VLR")
        if n_evlrs:
            table(evlr_start, n_evlrs, 60, "<Q", "EVLR")
    return out


def _las_crs(p: Path) -> CrsInfo:
    check_input_file(p)
    with foreign_errors(f"cannot read the header of {p}"):
        raw = las_crs_records(p)
    if 2112 in raw:
        text = raw[2112].decode("utf-8", errors="replace").rstrip("\0").strip()
        if text:
            return parse_wkt_crs(text)
    if 34735 in raw:
        return parse_geotiff_keys(raw[34735], raw.get(34736, b""), raw.get(34737, b""))
    return NO_CRS


# ----------------------------------------------------------------------------- GeoTIFF keys


def parse_geotiff_keys(directory: bytes, doubles: bytes = b"", ascii_params: bytes = b"") -> CrsInfo:
    """A CRS from the GeoTIFF key directory (and its double and ASCII parameters).

    Parameters
    ----------
    directory : bytes
        GeoKeyDirectoryTag: little-endian uint16, a 4-value header then one
        ``(key id, tag location, count, value or offset)`` entry per key.
    doubles, ascii_params : bytes
        GeoDoubleParamsTag (float64) and GeoAsciiParamsTag (text, ``|``-terminated).
    """
    words = np.frombuffer(directory[: len(directory) // 2 * 2], dtype="<u2")
    if words.size < 4:
        return NO_CRS
    n_keys = min(int(words[3]), (words.size - 4) // 4)
    entries = words[4 : 4 + 4 * n_keys].reshape(-1, 4)
    text = ascii_params.decode("ascii", errors="replace")
    keys: dict[int, int | str] = {}
    for key_id, location, count, value in entries.tolist():
        if location == 0:
            keys[key_id] = value
        elif location == 34737:
            keys[key_id] = text[value : value + count].rstrip("|\0 ")
    model = keys.get(GT_MODEL_TYPE)
    epsg = _code(keys.get(PROJECTED_CS_TYPE))
    geographic = model == 2
    if geographic and epsg is None:
        epsg = _code(keys.get(GEOGRAPHIC_TYPE))
    unit = EPSG_UNITS.get(_code(keys.get(PROJ_LINEAR_UNITS)) or 0)
    if unit is None and epsg is not None and not geographic:
        unit = _unit_of_epsg(epsg)
    vertical = EPSG_UNITS.get(_code(keys.get(VERTICAL_UNITS)) or 0)
    citation = keys.get(PCS_CITATION) or keys.get(GT_CITATION)
    description = citation if isinstance(citation, str) and citation else None
    if description is None and epsg is not None:
        description = f"EPSG:{epsg}"
    return CrsInfo(
        description=description, unit=None if geographic else unit, epsg=epsg,
        vertical_unit=vertical, geographic=geographic, source="geotiff",
    )


def _code(value: int | str | None) -> int | None:
    if isinstance(value, int) and 0 < value < _USER_DEFINED:
        return value
    return None


def _unit_of_epsg(epsg: int) -> CrsUnit | None:
    """Linear unit of a projected EPSG code: pyproj when installed, else the UTM
    families (WGS 84, NAD83, NAD27, ETRS89), which are all metres."""
    try:
        import pyproj  # optional
    except ImportError:
        utm = (32601 <= epsg <= 32660 or 32701 <= epsg <= 32760 or 26901 <= epsg <= 26923
               or 26701 <= epsg <= 26722 or 25828 <= epsg <= 25838)
        return "m" if utm else None
    try:
        axis = pyproj.CRS.from_epsg(epsg).axis_info
    except Exception:  # unknown code
        return None
    return _unit_of_factor(axis[0].unit_conversion_factor) if axis else None


# ----------------------------------------------------------------------------- WKT

_TOKEN = re.compile(r'\s*(?:"((?:[^"]|"")*)"|([\[\](),])|([^\[\](),"\s]+))')

_Node = tuple[str, list]  # (keyword, arguments: str | float | _Node)


def _parse_wkt(text: str) -> _Node:
    """WKT (version 1 or 2) as nested ``(KEYWORD, [args])``; strings stay str,
    numbers become float."""
    tokens: list[tuple[str, str]] = []
    pos = 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if not m or m.end() == pos:
            break
        pos = m.end()
        if m.group(1) is not None:
            tokens.append(("str", m.group(1).replace('""', '"')))
        elif m.group(2):
            tokens.append(("punct", m.group(2)))
        elif m.group(3):
            tokens.append(("word", m.group(3)))
    stack: list[_Node] = [("", [])]
    last_word: str | None = None
    for kind, tok in tokens:
        if kind == "punct":
            if tok in "[(":
                node: _Node = (last_word or "", [])
                stack[-1][1].append(node)
                stack.append(node)
                last_word = None
            elif tok in "])":
                if last_word is not None:
                    stack[-1][1].append(_number(last_word))
                    last_word = None
                if len(stack) > 1:
                    stack.pop()
            elif last_word is not None:  # comma after a bare value
                stack[-1][1].append(_number(last_word))
                last_word = None
        elif kind == "word":
            last_word = tok
        else:
            stack[-1][1].append(tok)
    roots = [a for a in stack[0][1] if isinstance(a, tuple)]
    if not roots:
        raise ValueError("no WKT keyword")
    return roots[0]


def _number(word: str) -> float | str:
    try:
        return float(word)
    except ValueError:
        return word


def _children(node: _Node, *keywords: str) -> list[_Node]:
    return [a for a in node[1] if isinstance(a, tuple) and a[0].upper() in keywords]


_PROJECTED = ("PROJCS", "PROJCRS", "PROJECTEDCRS")
_GEOGRAPHIC = ("GEOGCS", "GEOGCRS", "GEOGRAPHICCRS", "GEODCRS", "GEODETICCRS", "GEOCCS")
_VERTICAL = ("VERT_CS", "VERTCS", "VERTCRS", "VERTICALCRS")
_COMPOUND = ("COMPD_CS", "COMPOUNDCRS")
_UNITS = ("UNIT", "LENGTHUNIT")


def parse_wkt_crs(text: str) -> CrsInfo:
    """A CRS from OGC WKT (version 1 or 2, ESRI flavour included).

    The horizontal unit is the projected CRS's own UNIT (WKT 1) or LENGTHUNIT
    (WKT 2, on the CS or on an axis), classified by its conversion factor to
    metres; a geographic CRS has no linear unit. The EPSG code is the AUTHORITY or
    ID of the (horizontal) CRS.
    """
    try:
        root = _parse_wkt(text)
    except ValueError:
        return CrsInfo(description=text, source="wkt")
    horizontal, vertical = root, None
    if root[0].upper() in _COMPOUND:
        parts = [a for a in root[1] if isinstance(a, tuple)]
        horizontal = next((a for a in parts if a[0].upper() in _PROJECTED + _GEOGRAPHIC), root)
        vertical = next((a for a in parts if a[0].upper() in _VERTICAL), None)
    elif root[0].upper() in _VERTICAL:
        horizontal, vertical = root, root
    geographic = horizontal[0].upper() in _GEOGRAPHIC
    unit = None if geographic else _node_unit(horizontal)
    return CrsInfo(
        description=text, unit=unit, epsg=_node_epsg(horizontal),
        vertical_unit=None if vertical is None else _node_unit(vertical),
        geographic=geographic, source="wkt",
    )


def _node_unit(node: _Node) -> CrsUnit | None:
    candidates = _children(node, *_UNITS)
    for cs in _children(node, "CS", "AXIS"):
        candidates += _children(cs, *_UNITS)
    for axis in _children(node, "AXIS"):
        candidates += _children(axis, *_UNITS)
    for unit in candidates:
        factors = [a for a in unit[1] if isinstance(a, float)]
        if factors:
            found = _unit_of_factor(factors[0])
            if found is not None:
                return found
    return None


def _unit_of_factor(factor: float) -> CrsUnit | None:
    for unit, metres in (("m", 1.0), ("ft", 0.3048), ("us-ft", 1200.0 / 3937.0)):
        if abs(factor - metres) <= 1e-9 * metres:
            return unit  # type: ignore[return-value]
    return None


def _node_epsg(node: _Node) -> int | None:
    for ident in _children(node, "AUTHORITY", "ID"):
        args = ident[1]
        if len(args) >= 2 and str(args[0]).upper() == "EPSG":
            try:
                return int(float(args[1]))
            except (TypeError, ValueError):
                return None
    return None
