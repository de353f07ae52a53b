"""Out-of-core build of a COPC file from LAS/LAZ inputs (``rough-viewer index``).

Pass 1 streams the inputs in chunks, converts each point to the output format
(6, 7 or 8, extra bytes kept as raw bytes), fills the level-of-detail cells of the
nodes above the *bucket depth* (their points go to one file per node) and appends
the rest to one bucket file per node at the bucket depth. Pass 2 builds each
bucket's subtree in memory (:func:`~rough_viewer.io.copc.octree.build_subtree`)
and compresses one LAZ chunk per node, on ``workers`` processes; a bucket larger
than the memory allows is split again by streaming first.

Memory (:func:`plan_index`): pass 1 holds one chunk of ``chunk_points`` points
(about ``3 R + 150`` bytes each, R the record size); pass 2 holds one bucket of at
most ``bucket_points`` points per worker (about ``2 R + 200`` bytes each). Both are
sized from ``memory_bytes``; the disk holds one uncompressed copy of the points
(R bytes each) beside the output while it runs.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rough_viewer.io.copc import octree
from rough_viewer.io.copc.octree import Cube
from rough_viewer.io.copc.writer import CopcWriter, RawVlr, Summary, compress_chunk, laz_vlr
from rough_viewer.vocabulary import InputError

#: Bytes of a standard record of formats 6, 7, 8.
STANDARD_SIZE = {6: 30, 7: 36, 8: 38}
#: Most points a childless node keeps.
LEAF_POINTS = 50_000
#: Deepest bucket level of pass 1 (8**4 bucket files at most).
MAX_BUCKET_DEPTH = 4
_RGB = {2, 3, 5, 7, 8, 10}
_NIR = {8, 10}


@dataclass(frozen=True)
class Plan:
    """Everything the build needs, from the inputs' headers and ``--memory``.

    Attributes
    ----------
    paths : tuple of Path
    total : int
        Points declared by the headers.
    point_format : int
        Output format, 6, 7 or 8.
    extra_bytes : int
        Extra bytes per point (copied raw).
    scales, offsets : tuple of float
        Output scale and offset (units); the inputs' own when they all share them.
    same_grid : bool
        Whether every input has these scales and offsets (integers copied as stored).
    cube : Cube
    vlrs : tuple of RawVlr
        Extra-bytes and CRS VLRs of the first input.
    wkt : bool
    bucket_depth : int
    chunk_points, bucket_points : int
        Points per chunk of pass 1, most points per bucket of pass 2.
    workers : int
    """

    paths: tuple[Path, ...]
    total: int
    point_format: int
    extra_bytes: int
    scales: tuple[float, float, float]
    offsets: tuple[float, float, float]
    same_grid: bool
    cube: Cube
    vlrs: tuple[RawVlr, ...]
    wkt: bool
    bucket_depth: int
    chunk_points: int
    bucket_points: int
    workers: int

    @property
    def record_size(self) -> int:
        """Bytes per output point."""
        return STANDARD_SIZE[self.point_format] + self.extra_bytes


def memory_per_point(record_size: int) -> tuple[int, int]:
    """Bytes per point held by pass 1 (per chunk point) and pass 2 (per bucket point)."""
    return 3 * record_size + 150, 2 * record_size + 200


def disk_needed(plan: Plan) -> int:
    """Bytes of disk the build needs beside the output, at its peak: the
    uncompressed bucket copy of every point and the COPC file (counted at the
    record size over 3, more than LAZ usually takes)."""
    return plan.total * plan.record_size * 4 // 3


def check_disk(plan: Plan, folder: Path) -> None:
    """Refuse, in one line, a folder without room for :func:`disk_needed`."""
    free = shutil.disk_usage(folder).free
    need = disk_needed(plan)
    if need > free:
        raise InputError(f"index needs about {need / 1e9:.1f} GB of disk in {folder} "
                         f"(one uncompressed copy of the points, then the file); "
                         f"{free / 1e9:.1f} GB free")


def _open(path: Path):
    import laspy

    try:
        return laspy.open(path)
    except FileNotFoundError:
        raise InputError(f"no such file: {path}") from None
    except Exception as exc:  # laspy's errors have many types
        text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"cannot read {path} as LAS/LAZ: {text}") from None


def _header_facts(path: Path) -> dict:
    if path.suffix.lower() not in (".las", ".laz"):
        raise InputError(f"index reads LAS/LAZ files only: {path}")
    with _open(path) as r:
        h = r.header
        pf = h.point_format
        vlrs = []
        for v in h.vlrs:
            uid = getattr(v, "user_id", "")
            if uid in ("LASF_Projection", "LASF_Spec") and (
                    uid == "LASF_Projection" or v.record_id == 4):
                vlrs.append(RawVlr(uid, int(v.record_id), str(getattr(v, "description", "")),
                                   bytes(v.record_data_bytes())))
        return {
            "format": int(pf.id), "size": int(pf.size), "extra": int(pf.num_extra_bytes),
            "extra_names": tuple(pf.extra_dimension_names), "count": int(h.point_count),
            "scales": tuple(float(s) for s in h.scales),
            "offsets": tuple(float(o) for o in h.offsets),
            "mins": np.asarray(h.mins, float), "maxs": np.asarray(h.maxs, float), "vlrs": vlrs,
            "wkt": any(v.user_id == "LASF_Projection" and v.record_id == 2112 for v in vlrs),
        }


def _wkt_of_epsg(path: Path, vlrs: list[RawVlr]) -> tuple[list[RawVlr], bool]:
    """The CRS VLRs for a 1.4 file: a WKT one kept as it is; GeoTIFF keys that give
    an EPSG code replaced by its WKT (pyproj); else the VLRs as they are."""
    if any(v.user_id == "LASF_Projection" and v.record_id == 2112 for v in vlrs):
        return vlrs, True
    from rough_viewer.io.formats.crs import read_crs

    epsg = read_crs(path).epsg
    try:
        import pyproj

        wkt = pyproj.CRS.from_epsg(epsg).to_wkt("WKT1_GDAL") if epsg else None
    except Exception:  # no pyproj, an unknown code: keep the keys
        wkt = None
    if not wkt:
        return vlrs, False
    kept = [v for v in vlrs if v.user_id != "LASF_Projection"]
    return [*kept, RawVlr("LASF_Projection", 2112, "OGC WKT", wkt.encode() + b"\0")], True


def plan_index(paths: list[Path], *, memory_bytes: int, workers: int = 1) -> Plan:
    """Read the inputs' headers and size the two passes for ``memory_bytes``.

    Raises
    ------
    InputError
        A file that is not LAS/LAZ or cannot be read; inputs whose extra bytes
        differ; a memory budget too small for 10,000 points a pass.
    """
    facts = [_header_facts(p) for p in paths]
    first = facts[0]
    for p, f in zip(paths, facts, strict=True):
        if (f["extra"], f["extra_names"]) != (first["extra"], first["extra_names"]):
            names = ", ".join(f["extra_names"]) or "none"
            raise InputError(f"{p} has other extra dimensions ({names}) than {paths[0]}; "
                             "index needs the same ones")
    formats = {f["format"] for f in facts}
    fmt = 8 if formats & _NIR else 7 if formats & _RGB else 6
    same = all(f["scales"] == first["scales"] and f["offsets"] == first["offsets"] for f in facts)
    scales = tuple(min(f["scales"][i] for f in facts) for i in range(3))
    offsets = first["offsets"]
    mins = np.min([f["mins"] for f in facts], axis=0)
    maxs = np.max([f["maxs"] for f in facts], axis=0)
    total = sum(f["count"] for f in facts)
    record = STANDARD_SIZE[fmt] + first["extra"]
    per1, per2 = memory_per_point(record)
    workers = max(1, workers)
    chunk = min(2_000_000, int(memory_bytes * 0.4 // per1))
    bucket = int(memory_bytes * 0.8 // (per2 * workers))
    if chunk < 10_000 or bucket < 10_000:
        need = max(per1 * 10_000 / 0.4, per2 * workers * 10_000 / 0.8)
        raise InputError(f"--memory {memory_bytes / 1e6:.0f} MB is too small for index "
                         f"(at least {need / 1e6:.0f} MB with {workers} worker(s))")
    depth = 0
    while total > bucket // 2 * 4 ** depth and depth < MAX_BUCKET_DEPTH:
        depth += 1
    vlrs, wkt = _wkt_of_epsg(paths[0], first["vlrs"])
    return Plan(paths=tuple(paths), total=total, point_format=fmt, extra_bytes=first["extra"],
                scales=scales, offsets=offsets, same_grid=same,
                cube=octree.cube_of_bounds(mins, maxs), vlrs=tuple(vlrs),
                wkt=wkt, bucket_depth=depth, chunk_points=chunk,
                bucket_points=bucket, workers=workers)


def convert(points, plan: Plan) -> np.ndarray:
    """Records of one laspy chunk in the output layout: (N, record_size) uint8.

    Every dimension the output format has and the input has is copied (a 0-5
    input's scan angle rank, in degrees, becomes the scan angle in 0.006 degree
    steps); the extra bytes are copied as they are.
    """
    import laspy

    n = len(points)
    out = laspy.PackedPointRecord.zeros(n, laspy.PointFormat(plan.point_format))
    have = set(points.point_format.dimension_names)
    for name in out.point_format.dimension_names:
        if name in ("X", "Y", "Z"):
            continue
        if name in have:
            out[name] = points[name]
    if "scan_angle_rank" in have and "scan_angle" not in have:
        out["scan_angle"] = np.round(np.asarray(points["scan_angle_rank"], float) / 0.006)
    if plan.same_grid:
        for axis in "XYZ":
            out[axis] = points[axis]
    else:
        for i, axis in enumerate("xyz"):
            ints = np.round((np.asarray(points[axis]) - plan.offsets[i]) / plan.scales[i])
            if ints.size and (ints.min() < -2**31 or ints.max() >= 2**31):
                raise InputError("coordinates do not fit the output's scale and offset "
                                 "(inputs with far apart scales or offsets)")
            out["XYZ"[i]] = ints.astype(np.int32)
    raw = np.empty((n, plan.record_size), np.uint8)
    std = STANDARD_SIZE[plan.point_format]
    raw[:, :std] = out.array.view(np.uint8).reshape(n, std)
    if plan.extra_bytes:
        src = points.array.view(np.uint8).reshape(n, -1)
        raw[:, std:] = src[:, src.shape[1] - plan.extra_bytes:]
    return raw


def ints_of(raw: np.ndarray) -> np.ndarray:
    """X, Y, Z integers (N, 3) of output records (their first 12 bytes)."""
    return np.ascontiguousarray(raw[:, :12]).view("<i4").reshape(-1, 3)


def lattice(raw: np.ndarray, plan: Plan) -> np.ndarray:
    """Lattice coordinates (:func:`~rough_viewer.io.copc.octree.quantize`) of records."""
    xyz = ints_of(raw) * np.asarray(plan.scales) + np.asarray(plan.offsets)
    return octree.quantize(xyz, plan.cube)


def _name(depth: int, key: np.ndarray | tuple[int, ...]) -> str:
    return f"{depth}-{int(key[0])}-{int(key[1])}-{int(key[2])}.bin"


def _append_groups(folder: Path, raw: np.ndarray, codes: np.ndarray, depth: int) -> None:
    """Append each group of records (same node code) to its node's file."""
    if not codes.size:
        return
    order = np.argsort(codes, kind="stable")
    sorted_codes = codes[order]
    starts = np.flatnonzero(np.r_[True, np.diff(sorted_codes) != 0])
    ends = np.r_[starts[1:], codes.size]
    keys = octree.unpack(sorted_codes[starts])
    for s, e, k in zip(starts, ends, keys, strict=True):
        with open(folder / _name(depth, k), "ab") as fh:
            fh.write(raw[order[s:e]].tobytes())


def split(raw: np.ndarray, q: np.ndarray, d0: int, d1: int, taken: dict[int, np.ndarray],
          nodes: Path, buckets: Path) -> None:
    """Stream step: fill the level-of-detail cells of depths ``d0 .. d1-1`` (cells
    already filled by earlier chunks in ``taken``), append those points to their
    node files in ``nodes`` and the rest to their depth-``d1`` bucket files."""
    for d in range(d0, d1):
        chosen, taken[d] = octree.first_per_cell(octree.cell_codes(q, d), taken.get(d))
        _append_groups(nodes, raw[chosen], octree.node_codes(q[chosen], d), d)
        raw, q = raw[~chosen], q[~chosen]
    _append_groups(buckets, raw, octree.node_codes(q, d1), d1)


@dataclass
class _Totals:
    count: int = 0
    lo: np.ndarray | None = None
    hi: np.ndarray | None = None
    by_return: np.ndarray | None = None
    gps: tuple[float, float] = (np.inf, -np.inf)

    def add(self, raw: np.ndarray) -> None:
        if not raw.shape[0]:
            return
        ints = ints_of(raw)
        lo, hi = ints.min(axis=0), ints.max(axis=0)
        self.lo = lo if self.lo is None else np.minimum(self.lo, lo)
        self.hi = hi if self.hi is None else np.maximum(self.hi, hi)
        returns = np.bincount(raw[:, 14] & 0x0F, minlength=16)[1:16]
        self.by_return = returns if self.by_return is None else self.by_return + returns
        gps = np.ascontiguousarray(raw[:, 22:30]).view("<f8")
        self.gps = (min(self.gps[0], float(gps.min())), max(self.gps[1], float(gps.max())))
        self.count += raw.shape[0]

    def summary(self, plan: Plan) -> Summary:
        sc, of = np.asarray(plan.scales), np.asarray(plan.offsets)
        lo = (self.lo if self.lo is not None else np.zeros(3)) * sc + of
        hi = (self.hi if self.hi is not None else np.zeros(3)) * sc + of
        gps = self.gps if self.count else (0.0, 0.0)
        br = self.by_return if self.by_return is not None else np.zeros(15, int)
        return Summary(self.count, tuple(lo), tuple(hi), tuple(int(v) for v in br),
                       gps)


def _check_inside(totals: _Totals, plan: Plan) -> None:
    """Refuse inputs without points, and points outside the cube made from the
    headers' bounding boxes (a header that lies): their nodes would not hold them."""
    if totals.lo is None or totals.hi is None:
        raise InputError("the inputs hold no points")
    sc, of = np.asarray(plan.scales), np.asarray(plan.offsets)
    lo, hi = totals.lo * sc + of, totals.hi * sc + of
    c, h = np.asarray(plan.cube.center), plan.cube.halfsize
    if (lo < c - h).any() or (hi > c + h).any():
        raise InputError("points lie outside the bounding boxes the input headers declare "
                         "(a damaged header); rewrite the files (e.g. with PDAL or lasinfo "
                         "-repair_bb) and index again")


def _read_inputs(plan: Plan) -> Iterator[np.ndarray]:
    for path in plan.paths:
        with _open(path) as r:
            try:
                for points in r.chunk_iterator(plan.chunk_points):
                    yield convert(points, plan)
            except InputError:
                raise
            except Exception as exc:
                raise InputError(f"cannot decode {path}: {str(exc).splitlines()[0]}") from None


def _file_chunks(path: Path, plan: Plan) -> Iterator[np.ndarray]:
    n = path.stat().st_size // plan.record_size
    mm = np.memmap(path, np.uint8, "r", shape=(n, plan.record_size))
    for s in range(0, n, plan.chunk_points):
        yield np.array(mm[s:s + plan.chunk_points])


def _build_bucket(args: tuple[str, int, int, int, int]
                  ) -> list[tuple[int, tuple[int, int, int], int, bytes]]:
    """Pass 2 on one bucket file (run in a worker): its nodes' LAZ chunks."""
    path, depth, fmt, extra, record = args
    raw = np.fromfile(path, np.uint8).reshape(-1, record)
    plan_q = _LATTICE
    assert plan_q is not None
    q = lattice(raw, plan_q)
    tree = octree.build_subtree(q, depth, leaf_points=LEAF_POINTS)
    vlr = laz_vlr(fmt, extra)
    out = []
    start = 0
    for d, key, count in zip(tree.depths, tree.keys, tree.counts, strict=True):
        sel = raw[tree.order[start:start + count]]
        start += count
        out.append((int(d), (int(key[0]), int(key[1]), int(key[2])), int(count),
                    compress_chunk(sel.tobytes(), vlr)))
    os.unlink(path)
    return out


_LATTICE: Plan | None = None


def _init_worker(plan: Plan) -> None:
    global _LATTICE
    _LATTICE = plan


def _final_buckets(plan: Plan, nodes: Path, buckets: Path, tick: Callable[[int], None]
                   ) -> list[tuple[Path, int]]:
    """The bucket files, those over ``bucket_points`` split again (streaming)."""
    todo = sorted(buckets.iterdir())
    final: list[tuple[Path, int]] = []
    while todo:
        path = todo.pop()
        depth = int(path.name.split("-")[0])
        n = path.stat().st_size // plan.record_size
        if n <= plan.bucket_points or depth >= octree.MAX_DEPTH:
            final.append((path, depth))
            continue
        sub = buckets / f"split-{path.stem}"
        sub.mkdir()
        taken: dict[int, np.ndarray] = {}
        for raw in _file_chunks(path, plan):
            split(raw, lattice(raw, plan), depth, depth + 1, taken, nodes, sub)
        path.unlink()
        for child in sub.iterdir():
            target = buckets / child.name
            child.rename(target)
            todo.append(target)
        sub.rmdir()
    return final


def build_copc(plan: Plan, out: Path, *, work_dir: Path,
               progress: Callable[[int, int], None] | None = None) -> Summary:
    """Write the COPC file of ``plan``'s inputs to ``out``.

    Parameters
    ----------
    plan : Plan
    out : Path
        The file to write (a temporary name; the caller renames it).
    work_dir : Path
        Folder for the temporary node and bucket files (removed at the end).
    progress : callable, optional
        ``progress(done, total)`` in points, twice the point count in all (read,
        then written).

    Returns
    -------
    Summary
        The points written.
    """
    tmp = Path(tempfile.mkdtemp(prefix=".index-", dir=work_dir))
    nodes, buckets = tmp / "nodes", tmp / "buckets"
    nodes.mkdir()
    buckets.mkdir()
    done = [0]
    total = [2 * plan.total]

    def tick(n: int) -> None:
        done[0] += n
        if progress is not None:
            progress(done[0], max(total[0], done[0]))

    writer = None
    try:
        totals = _Totals()
        taken: dict[int, np.ndarray] = {}
        for raw in _read_inputs(plan):
            totals.add(raw)
            split(raw, lattice(raw, plan), 0, plan.bucket_depth, taken, nodes, buckets)
            tick(raw.shape[0])
        del taken
        _check_inside(totals, plan)
        total[0] = 2 * totals.count
        writer = CopcWriter(out, plan.point_format, plan.record_size, plan.scales,
                            plan.offsets, plan.cube, list(plan.vlrs), plan.wkt)
        _write_nodes(writer, plan, nodes, tick)
        final = _final_buckets(plan, nodes, buckets, tick)
        _write_nodes(writer, plan, nodes, tick)  # those the splits made
        _write_buckets(writer, plan, final, tick)
        summary = totals.summary(plan)
        writer.close(summary)
        return summary
    finally:
        if writer is not None:
            writer.abort()
        shutil.rmtree(tmp, ignore_errors=True)


def _write_nodes(writer: CopcWriter, plan: Plan, nodes: Path, tick: Callable[[int], None]
                 ) -> None:
    vlr = laz_vlr(plan.point_format, plan.extra_bytes)
    for path in sorted(nodes.iterdir(), key=lambda p: [int(v) for v in p.stem.split("-")]):
        data = path.read_bytes()
        count = len(data) // plan.record_size
        d, x, y, z = (int(v) for v in path.stem.split("-"))
        writer.add_node(d, (x, y, z), count, compress_chunk(data, vlr))
        path.unlink()
        tick(count)


def _write_buckets(writer: CopcWriter, plan: Plan, final: list[tuple[Path, int]],
                   tick: Callable[[int], None]) -> None:
    jobs = [(str(p), d, plan.point_format, plan.extra_bytes, plan.record_size) for p, d in final]
    if plan.workers <= 1 or len(jobs) <= 1:
        _init_worker(plan)
        results: Iterator = map(_build_bucket, jobs)
        _emit(writer, results, tick)
        return
    import multiprocessing

    ctx = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(plan.workers, mp_context=ctx, initializer=_init_worker,
                               initargs=(plan,))
    try:
        _emit(writer, pool.map(_build_bucket, jobs), tick)
    except BaseException:  # an error or Ctrl-C: drop the buckets not started
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown()


def _emit(writer: CopcWriter, results: Iterator, tick: Callable[[int], None]) -> None:
    for nodes in results:
        for d, key, count, chunk in nodes:
            writer.add_node(d, key, count, chunk)
            tick(count)
