"""The coordinate reference system (CRS) a point file declares: its name, EPSG code
and linear units, horizontal and vertical.

A WKT is parsed by pyproj where it is installed (the optional extra ``crs``: every
WKT flavour PROJ reads, compound CRSs with their vertical unit, bound CRSs), else,
or where pyproj cannot read it, by the small reader here (:func:`parse_wkt_text`:
WKT 1 and 2, ESRI's flavour, compound CRSs), which stays as the fallback so that a
plain install reads the common files. Either runs in the reader child where reads
are isolated (:func:`read_crs`): the parent never parses a file's WKT, with pyproj
or without, and checks the child's small answer field by field.

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

import dataclasses
import importlib.util
import os
import re
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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


#: Address space a child may add to read a file's CRS, bytes: a WKT of at most
#: :data:`~rough_viewer.io.formats.las.MAX_CRS_RECORD_BYTES` parses in ~16 MB; tags larger
#: than this allows are a crafted file.
CRS_READ_BUDGET = 256 << 20
#: The format of a CRS's file as messages name it, by suffix.
_CRS_LABELS = {".las": "LAS", ".laz": "LAZ", ".tif": "GeoTIFF", ".tiff": "GeoTIFF",
               ".asc": "ESRI grid"}


def read_crs(path: str | os.PathLike[str]) -> CrsInfo:
    """The CRS a point file declares (header only; no points are decoded).

    A WKT (LAS record or ``.prj``) and GeoTIFF tags are parsed in a reader child
    process where reads are isolated (:func:`rough_viewer.io.sandbox.isolate.call_isolated`;
    the answer kept for the file's identity, :data:`CRS_CACHE_ENTRIES`), and every
    record is bounded in bytes before it is read (:func:`crs_here`). This process
    walks a LAS header's record table (bounded: :func:`~rough_viewer.io.formats.las.check_las_layout`),
    parses a LAS file's GeoKeys when it has no WKT (three records of at most
    :data:`~rough_viewer.io.formats.las.MAX_CRS_RECORD_BYTES`: ~1 MB of work), and checks the
    child's answer.

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
        A LAS/LAZ file whose header cannot be read, a CRS record or ``.prj`` longer
        than :data:`~rough_viewer.io.formats.las.MAX_CRS_RECORD_BYTES`, a reader that failed.
    """
    from rough_viewer.io.sandbox import isolate

    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".e57":
        return CrsInfo(description=None, unit="m", source="e57")
    if suffix not in _CRS_LABELS:
        return NO_CRS
    described = p
    if suffix in (".las", ".laz"):
        from rough_viewer.io.formats.las import check_las_layout

        check_input_file(p)
        records = {record_id for record_id, _, _ in check_las_layout(p).crs_records}
        if not records:
            return NO_CRS
        if WKT_RECORD not in records and importlib.util.find_spec("pyproj") is None:
            return _las_crs(p)  # GeoKeys only: 3 x 64 KiB at most, parsed in ~1 MB here
            # (with pyproj, its EPSG look-ups run in the child too)
    elif suffix == ".asc":
        from rough_viewer.io.formats.dem import prj_beside

        prj = prj_beside(p)
        if prj is None:
            return NO_CRS
        described = prj
    else:
        check_input_file(p)
    if not isolate.available():
        return crs_here(p)
    key = _identity(p, described)
    with _cache_lock:
        known = _cache.get(key)
    if known is not None:
        return known
    value = isolate.call_isolated(
        f"{__name__}:crs_fields", p, label=_CRS_LABELS[suffix],
        limits=isolate.Limits(memory=CRS_READ_BUDGET, seconds=isolate.time_limit(0)))
    info = crs_from_fields(value, p)
    with _cache_lock:
        if len(_cache) >= CRS_CACHE_ENTRIES:
            _cache.pop(next(iter(_cache)))
        _cache[key] = info
    return info


#: The LAS record id of a CRS as OGC WKT.
WKT_RECORD = 2112
#: CRSs read in a child kept in this process (a command reads a file's CRS two or
#: three times: units first, then with its points), by the file's identity.
CRS_CACHE_ENTRIES = 64
_cache: dict[tuple[object, ...], CrsInfo] = {}
_cache_lock = threading.Lock()


def _identity(*paths: Path) -> tuple[object, ...]:
    """What changes when a file is replaced or written: its name, device, inode, size
    and modification time (of each of ``paths``)."""
    key: list[object] = []
    for q in paths:
        st = q.stat()
        key += [os.path.realpath(q), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns]
    return tuple(key)


def crs_here(p: Path) -> CrsInfo:
    """:func:`read_crs` in this process (the reader child's part)."""
    suffix = p.suffix.lower()
    if suffix in (".las", ".laz"):
        return _las_crs(p)
    if suffix in (".tif", ".tiff"):
        return _geotiff_crs(p)
    if suffix == ".asc":
        return _prj_crs(p)
    return NO_CRS


def crs_fields(p: Path, **_: object) -> dict[str, object]:
    """:func:`crs_here` as JSON fields (what the reader child sends back)."""
    return dataclasses.asdict(crs_here(p))


_UNITS_KNOWN = frozenset(EPSG_UNITS.values())
_SOURCES = frozenset({"", "wkt", "geotiff", "e57"})


def crs_from_fields(value: object, p: Path) -> CrsInfo:
    """The :class:`CrsInfo` of a reader child's answer (:func:`crs_fields`), every
    field checked: text, a known unit, a whole EPSG code, a flag, a known source.

    Raises InputError naming ``p`` for anything else."""
    fields = {f.name for f in dataclasses.fields(CrsInfo)}
    ok = isinstance(value, dict) and set(value) <= fields
    if ok:
        assert isinstance(value, dict)
        d, e = value.get("description"), value.get("epsg")
        ok = ((d is None or isinstance(d, str))
              and (e is None or isinstance(e, int) and not isinstance(e, bool))
              and all(value.get(k) is None or value.get(k) in _UNITS_KNOWN
                      for k in ("unit", "vertical_unit"))
              and isinstance(value.get("geographic", False), bool)
              and value.get("source", "") in _SOURCES)
    if not ok:
        raise InputError(f"the CRS reader gave a damaged answer for {p}")
    assert isinstance(value, dict)
    return CrsInfo(**value)


def _geotiff_crs(p: Path) -> CrsInfo:
    """The GeoKeys of a GeoTIFF raster (the same keys a LAS file may carry)."""
    from rough_viewer.io.formats.dem import GEO_KEY_DIRECTORY, geokey_bytes, geotiff_tags

    check_input_file(p)
    with foreign_errors(f"cannot read the tags of {p}"):
        tags = geotiff_tags(p)
    if GEO_KEY_DIRECTORY not in tags:
        return NO_CRS
    return parse_geotiff_keys(*geokey_bytes(tags))


def _prj_crs(p: Path) -> CrsInfo:
    """The WKT of the ``.prj`` file beside an ESRI ASCII grid, if any (at most
    :data:`~rough_viewer.io.formats.las.MAX_CRS_RECORD_BYTES`)."""
    from rough_viewer.io.formats.dem import prj_beside
    from rough_viewer.io.formats.las import MAX_CRS_RECORD_BYTES

    prj = prj_beside(p)
    if prj is None:
        return NO_CRS
    with foreign_errors(f"cannot read {prj}"):
        with open(prj, "rb") as fh:
            data = fh.read(MAX_CRS_RECORD_BYTES + 1)
    if len(data) > MAX_CRS_RECORD_BYTES:
        raise InputError(f"{prj} is longer than the {MAX_CRS_RECORD_BYTES:,} bytes a CRS "
                         "(WKT) takes: not a .prj file")
    text = data.decode("utf-8", errors="replace").strip()
    return parse_wkt_crs(text) if text else NO_CRS


def _las_crs(p: Path) -> CrsInfo:
    """The CRS records of a LAS/LAZ file, read from their raw bytes (each at most
    :data:`~rough_viewer.io.formats.las.MAX_CRS_RECORD_BYTES`) without laspy."""
    from rough_viewer.io.formats.las import check_las_layout, las_crs_records

    check_input_file(p)
    raw = las_crs_records(p, check_las_layout(p))
    if WKT_RECORD in raw:
        text = raw[WKT_RECORD].decode("utf-8", errors="replace").rstrip("\0").strip()
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
    if vertical is None and _code(keys.get(VERTICAL_CS_TYPE)) is not None:
        vertical = _unit_of_epsg(_code(keys.get(VERTICAL_CS_TYPE)) or 0, projected=False)
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


def _pyproj() -> Any:
    """The pyproj module where it is installed (the optional extra ``crs``), else None."""
    try:
        import pyproj
    except ImportError:
        return None
    return pyproj


def _unit_of_epsg(epsg: int, *, projected: bool = True) -> CrsUnit | None:
    """Linear unit of an EPSG code (a projected CRS, or a vertical one): pyproj when
    installed, else the UTM families (WGS 84, NAD83, NAD27, ETRS89), which are all
    metres, and no vertical code."""
    pyproj = _pyproj()
    if pyproj is None:
        utm = (32601 <= epsg <= 32660 or 32701 <= epsg <= 32760 or 26901 <= epsg <= 26923
               or 26701 <= epsg <= 26722 or 25828 <= epsg <= 25838)
        return "m" if utm and projected else None
    try:
        axis = pyproj.CRS.from_epsg(epsg).axis_info
    except Exception:  # unknown code: pyproj.exceptions.CRSError
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
    """A CRS from OGC WKT: by pyproj where it is installed and reads it
    (:func:`_pyproj_wkt_crs`), else by :func:`parse_wkt_text`.

    The horizontal unit is the (projected) CRS's linear unit, a geographic or
    geocentric CRS having none; the vertical unit that of a compound CRS's vertical
    part (or of a vertical CRS); the EPSG code the one the (horizontal) CRS declares
    (its AUTHORITY or ID: never a code looked up for a CRS that gives none).
    """
    pyproj = _pyproj()
    if pyproj is not None:
        found = _pyproj_wkt_crs(pyproj, text)
        if found is not None:
            return found
    return parse_wkt_text(text)


def _pyproj_wkt_crs(pyproj: Any, text: str) -> CrsInfo | None:
    """:func:`parse_wkt_crs` by pyproj; None where pyproj cannot read ``text``."""
    try:
        crs = pyproj.CRS.from_wkt(text)
    except Exception:  # pyproj.exceptions.CRSError, and PROJ's parser on odd text
        return None
    crs = _unbound(crs)
    horizontal, vertical = crs, None
    if crs.is_compound:
        parts = [_unbound(c) for c in crs.sub_crs_list]
        horizontal = next((c for c in parts if not c.is_vertical), crs)
        vertical = next((c for c in parts if c.is_vertical), None)
    elif crs.is_vertical:
        horizontal, vertical = crs, crs
    geographic = bool(horizontal.is_geographic or horizontal.is_geocentric)
    return CrsInfo(
        description=text, unit=None if geographic else _pyproj_unit(horizontal),
        epsg=_pyproj_epsg(horizontal),
        vertical_unit=None if vertical is None else _pyproj_unit(vertical),
        geographic=geographic, source="wkt",
    )


def _unbound(crs: Any) -> Any:
    """The source CRS of a bound CRS (a WKT 1 TOWGS84), else ``crs``."""
    return crs.source_crs if crs.is_bound and crs.source_crs is not None else crs


def _pyproj_unit(crs: Any) -> CrsUnit | None:
    """Linear unit of a pyproj CRS's first axis (None for an angular or unknown one)."""
    axes = crs.axis_info
    return _unit_of_factor(axes[0].unit_conversion_factor) if axes else None


def _pyproj_epsg(crs: Any) -> int | None:
    """The EPSG code a pyproj CRS declares (its PROJJSON ``id``, or the first of its
    ``ids``); None where it declares none."""
    found = crs.to_json_dict()
    ids = [found["id"]] if "id" in found else list(found.get("ids", ()))
    for ident in ids:
        if str(ident.get("authority", "")).upper() == "EPSG":
            try:
                return int(ident["code"])
            except (KeyError, TypeError, ValueError):
                return None
    return None


def parse_wkt_text(text: str) -> CrsInfo:
    """A CRS from OGC WKT (version 1 or 2, ESRI flavour included) by the reader here,
    without pyproj (:func:`parse_wkt_crs`'s fallback).

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
