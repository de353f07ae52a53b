"""A semivariogram estimated from a random sample of cell pairs, with a standard
error per lag bin (for maps whose exact semivariogram would take too long).

Every lag bin ``k`` of :mod:`rough_viewer.grid.variogram` is a finite population of
ordered cell pairs; ``gamma(k)`` is the mean of ``(Z_i - Z_j)^2 / 2`` over it. Both
stages below draw pairs that are, given the bin they fall in, independent and
uniformly distributed over that bin's pairs (with replacement). The pooled sample
mean of a bin is therefore an unbiased estimate of ``gamma(k)`` and its standard
error is the sample standard deviation over the square root of the number of
sampled pairs ``n_k`` (no finite-population correction: draws are with
replacement).

Stage 1, uniform pairs: ``i`` uniform over the cells, ``j`` uniform over the other
cells. A bin receives pairs in proportion to its population, so the long lags (most
pairs) are well covered and the first bins, whose pairs are few, poorly.

Stage 2, short lags by lag vectors: for a bin ``k`` that stage 1 left short, ``i``
uniform over the cells and a lag vector ``h`` drawn uniformly among the integer
vectors of the bin (a point uniform in the spherical shell widened by half a cell
diagonal, rounded to the nearest integer vector, kept when that vector lies in the
bin: every integer vector of the bin owns a whole unit cube of the widened shell,
so each is equally likely); the pair ``(i, i + h)`` is kept when ``i + h`` is a
cell (a sorted-key lookup). Kept pairs are uniform over the bin's pairs
(rejection sampling). The number of proposals per bin follows a pilot round's
acceptance rate, so the bins end with similar ``n_k``; the allocation depends only
on where the cells are, never on their values, which keeps the estimate unbiased.

Pair counts are estimated too: from stage 1 ``n_k / samples * M (M - 1)`` and from
stage 2 ``n_k / proposals_k * M * V_k`` (``V_k`` the widened shell's volume), the
one with more sampled pairs, halved for unordered pairs.

Several maps of one grid (same cells, different values and missing cells) share
the draws: a pair enters a map's estimate when both its cells have a value there,
which keeps it uniform over that map's pairs.

Cost: time ``O(M + samples + proposals)`` (about :data:`CELL_SAMPLE_SECONDS` a cell,
:data:`PAIR_SAMPLE_SECONDS` and :data:`PROPOSAL_SECONDS` each, plus
:data:`MAP_SAMPLE_SECONDS` per map), memory ``O(M + CHUNK)``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from rough_viewer.vocabulary import ProgressFn

_Tick = Callable[[int], None]
"""``tick(done)``: proposals of stage 2 drawn so far."""

#: Pairs (or proposals) drawn at once: memory about ``CHUNK * 200`` bytes, and a
#: progress call (where a cancelled job stops) after each chunk.
CHUNK = 1 << 18
#: Estimated seconds per uniformly drawn pair (draw, distance, bin), per lag-vector
#: proposal (draw, bin, bitmap and sorted-key lookup) and per pair and map (values,
#: sums); measured on the project's 2-core machine, load average about 3
#: (benchmarks/bench_panels.py).
PAIR_SAMPLE_SECONDS = 7.0e-8
PROPOSAL_SECONDS = 1.5e-7
MAP_SAMPLE_SECONDS = 4.0e-8
#: Estimated fixed seconds per cell (the cells' table, sorted keys, bitmap).
CELL_SAMPLE_SECONDS = 1.2e-7
#: Share of the time budget spent on stage 1 (uniform pairs); the rest on stage 2.
UNIFORM_SHARE = 0.5
#: Fewest pairs and proposals a sampled estimate draws, whatever the budget.
MIN_SAMPLES = 50_000
#: Share of stage 2's proposals spent on the pilot round.
PILOT_SHARE = 0.2
#: Bytes per cell: sorted keys and their order, the table of indices (and 8 bytes
#: a map).
BYTES_PER_CELL = 96
#: Largest occupancy bitmap of the occupied box (one bit a cell) that stage 2
#: builds to skip the sorted-key lookup of most proposals, bytes.
BITMAP_BYTES = 32 * 2**20
#: Bytes per drawn pair or proposal of a chunk at the peak.
BYTES_PER_DRAW = 200


@dataclass(frozen=True)
class SampledSums:
    """Per lag bin (index k - 1) sums of one map's sampled pairs."""

    n: np.ndarray
    """(K,) sampled pairs (both cells with a value)."""
    s1: np.ndarray
    """(K,) sum of ``(Z_i - Z_j)^2 / 2``."""
    s2: np.ndarray
    """(K,) sum of its square."""
    pairs: np.ndarray
    """(K,) estimated number of unordered pairs in the bin."""


def sample_sizes(budget_s: float, n_maps: int, n_cells: int = 0) -> tuple[int, int]:
    """Stage-1 pairs and stage-2 proposals that fit ``budget_s`` seconds of the
    cost model for ``n_maps`` maps of ``n_cells`` cells (the fixed cost per cell
    first; at least :data:`MIN_SAMPLES` each)."""
    per_map = MAP_SAMPLE_SECONDS * max(n_maps, 1)
    left = max(budget_s - CELL_SAMPLE_SECONDS * n_cells, 0.0)
    samples = int(UNIFORM_SHARE * left / (PAIR_SAMPLE_SECONDS + per_map))
    proposals = int((1.0 - UNIFORM_SHARE) * left / (PROPOSAL_SECONDS + per_map))
    return max(samples, MIN_SAMPLES), max(proposals, MIN_SAMPLES)


def sample_seconds(samples: int, proposals: int, n_maps: int, n_cells: int = 0) -> float:
    """Cost-model seconds of a sampled estimate."""
    per_map = MAP_SAMPLE_SECONDS * max(n_maps, 1)
    return (CELL_SAMPLE_SECONDS * n_cells + samples * (PAIR_SAMPLE_SECONDS + per_map)
            + proposals * (PROPOSAL_SECONDS + per_map))


def sample_bytes(n_cells: int, n_maps: int = 1) -> float:
    """Estimated peak memory of a sampled estimate, bytes."""
    return ((BYTES_PER_CELL + 24 * n_maps) * n_cells + BITMAP_BYTES
            + (BYTES_PER_DRAW + 48 * n_maps) * CHUNK)


class _Accumulator:
    """Sums per map and bin, and the geometry counts of each stage."""

    def __init__(self, idx: np.ndarray, zs: Sequence[np.ndarray], n_bins: int) -> None:
        self.zs = zs
        self.dims = int(idx.shape[1])
        self.table = np.empty((idx.shape[0], self.dims + len(zs)))
        """(M, D + maps): a cell's indices (exact as floats) and its value in every
        map, one row: one random gather brings all of a pair's end."""
        self.table[:, :self.dims] = idx
        for m, z in enumerate(zs):
            self.table[:, self.dims + m] = z
        size = n_bins + 1
        self.n = [np.zeros(size) for _ in zs]
        self.s1 = [np.zeros(size) for _ in zs]
        self.s2 = [np.zeros(size) for _ in zs]
        self.size = size

    def add(self, i: np.ndarray, j: np.ndarray, k: np.ndarray,
            into: list[np.ndarray] | None = None) -> None:
        """Add the pairs ``(i, j)`` of bins ``k`` to every map (and the per-map pair
        counts of this stage to ``into``)."""
        rows_i = np.take(self.table, i, axis=0)  # take: ~5x faster than fancy rows
        rows_j = np.take(self.table, j, axis=0)
        self.add_diff(k, rows_i[:, self.dims:] - rows_j[:, self.dims:], into)

    def add_diff(self, k: np.ndarray, diff: np.ndarray,
                 into: list[np.ndarray] | None = None) -> None:
        """Add pairs of bins ``k`` whose value differences are ``diff`` (n, maps);
        bin 0 takes what counts nowhere (pairs out of range, missing values)."""
        for m in range(len(self.zs)):
            e = diff[:, m]
            ok = np.isfinite(e)
            kk = np.where(ok, k, 0)
            half = np.where(ok, 0.5 * e * e, 0.0)
            cnt = np.bincount(kk, minlength=self.size).astype(np.float64)
            self.n[m] += cnt
            self.s1[m] += np.bincount(kk, weights=half, minlength=self.size)
            self.s2[m] += np.bincount(kk, weights=half * half, minlength=self.size)
            if into is not None:
                into[m] += cnt


def sampled_sums(
    idx: np.ndarray,
    shape: tuple[int, ...],
    zs: Sequence[np.ndarray],
    n_bins: int,
    scale: float,
    samples: int,
    proposals: int,
    *,
    seed: int = 0,
    progress: ProgressFn | None = None,
) -> list[SampledSums]:
    """Sampled sums of every map in ``zs`` over the cells ``idx``.

    Parameters
    ----------
    idx : (M, D) int64
        Distinct cell indices, minimum 0 per axis; ``shape`` their extent.
    zs : sequence of (M,) float
        One value per cell for each map; NaN where the map has none.
    n_bins : int
        Bins ``k = 1 .. n_bins``; the bin of a lag vector ``h`` (cells) is
        ``floor(|h| * scale + 0.5)`` with ``scale`` = cell size / bin width.
    samples, proposals : int
        Stage-1 pairs and most stage-2 proposals (module docstring).
    seed : int
        Seed of the random draws (the same seed and cells draw the same pairs).
    progress : callable, optional
        ``progress(done, total)`` after every chunk (an exception stops it).
    """
    m = int(idx.shape[0])
    rng = np.random.default_rng(seed)
    acc = _Accumulator(idx, zs, n_bins)
    total = samples + proposals
    if progress is not None:
        progress(0, total)
    geo_a = np.zeros(acc.size)
    from_a = [np.zeros(acc.size) for _ in zs]
    dims = acc.dims
    done = 0
    for start in range(0, samples, CHUNK):
        n = min(CHUNK, samples - start)
        i = rng.integers(0, m, n)
        j = (i + 1 + rng.integers(0, m - 1, n)) % m
        # index differences (whole numbers, exact) and value differences, one row
        diff = np.take(acc.table, i, axis=0) - np.take(acc.table, j, axis=0)
        d2 = diff[:, 0] * diff[:, 0]
        for a in range(1, dims):
            d2 += diff[:, a] * diff[:, a]
        k = np.floor(np.sqrt(d2) * scale + 0.5).astype(np.int64)
        k[k > n_bins] = 0  # bin 0: beyond the last lag (sliced off at the end)
        geo_a += np.bincount(k, minlength=acc.size)
        acc.add_diff(k, diff[:, dims:], from_a)
        done += n
        if progress is not None:
            progress(done, total)
    near = _ShortLags(idx, shape, scale, n_bins, rng, acc)
    near.run(geo_a, proposals, lambda d: None if progress is None else progress(done + d, total))
    if progress is not None:
        progress(total, total)
    ordered_all = float(m) * float(m - 1)
    out = []
    for q in range(len(zs)):
        est_a = from_a[q] / max(samples, 1) * ordered_all
        with np.errstate(invalid="ignore", divide="ignore"):
            est_b = np.where(near.tried > 0, near.found[q] / np.maximum(near.tried, 1)
                             * float(m) * near.volume, 0.0)
        use_b = (near.tried > 0) & (near.found[q] >= from_a[q])
        pairs = np.where(use_b, est_b, est_a) / 2.0
        out.append(SampledSums(n=acc.n[q][1:], s1=acc.s1[q][1:], s2=acc.s2[q][1:],
                               pairs=pairs[1:]))
    return out


def _water_level(have: np.ndarray, rate: np.ndarray, budget: float, target: float) -> float:
    """The count ``L`` (at most ``target``) every bin can be brought up to with
    ``budget`` proposals, bin ``b`` needing ``(L - have_b) / rate_b`` (the fewest
    pairs of any bin as large as the budget allows)."""
    def cost(level: float) -> float:
        return float((np.maximum(level - have, 0.0) / rate).sum())

    if cost(target) <= budget:
        return target
    lo, hi = float(have.min()), target
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if cost(mid) <= budget else (lo, mid)
    return lo


class _ShortLags:
    """Stage 2: lag-vector proposals for the bins stage 1 left short."""

    def __init__(self, idx: np.ndarray, shape: tuple[int, ...], scale: float, n_bins: int,
                 rng: np.random.Generator, acc: _Accumulator) -> None:
        self.idx = idx
        self.shape = np.array(shape, dtype=np.int64)
        self.dims = int(idx.shape[1])
        self.scale = scale
        self.n_bins = n_bins
        self.rng = rng
        self.acc = acc
        keys = np.ravel_multi_index(idx.T, shape)
        self.order = np.argsort(keys, kind="stable")
        self.keys = keys[self.order]
        volume = float(np.prod(np.array(shape, dtype=np.float64)))
        self.bits: np.ndarray | None = None
        if volume <= 8.0 * BITMAP_BYTES:  # occupancy, one bit per cell of the box
            bits = np.zeros(int(volume) // 8 + 1, dtype=np.uint8)
            byte = self.keys >> 3
            first = np.flatnonzero(np.r_[True, byte[1:] != byte[:-1]])
            bits[byte[first]] = np.bitwise_or.reduceat(
                (1 << (self.keys & 7)).astype(np.uint8), first)
            self.bits = bits
        size = n_bins + 1
        self.tried = np.zeros(size)
        self.found = [np.zeros(size) for _ in acc.zs]
        self.geo = np.zeros(size)
        # widened shells (cells): radii and volumes per bin
        half_diag = 0.5 * np.sqrt(self.dims)
        k = np.arange(size, dtype=np.float64)
        self.r_lo = np.maximum((k - 0.5) / scale - half_diag, 0.0)
        self.r_hi = (k + 0.5) / scale + half_diag
        unit = np.pi if self.dims == 2 else 4.0 * np.pi / 3.0
        self.volume = unit * (self.r_hi**self.dims - self.r_lo**self.dims)
        self.volume[0] = 0.0

    def run(self, geo_a: np.ndarray, proposals: int, progress: _Tick) -> None:
        """A pilot round over the short bins, then the rest of ``proposals`` where
        the pilot's acceptance says they bring the bins up to the typical count."""
        bins = np.arange(1, self.n_bins + 1)
        counts = geo_a[1:]
        target = float(np.median(counts)) if counts.size else 0.0
        short = bins[counts < target] if target > 0 else bins
        if short.size == 0 or proposals <= 0:
            return
        pilot = np.full(short.size, max(64, int(PILOT_SHARE * proposals) // short.size))
        used = self._draw(short, pilot, progress, 0)
        rate = (self.geo[short] + 1.0) / (self.tried[short] + 2.0)
        have = geo_a[short] + self.geo[short]
        level = _water_level(have, rate, float(max(proposals - used, 0)), target)
        need = np.maximum(level - have, 0.0) / rate
        self._draw(short, need.astype(np.int64), progress, used)

    def _draw(self, bins: np.ndarray, per_bin: np.ndarray, progress: _Tick,
              offset: int) -> int:
        """``per_bin[b]`` proposals for each bin of ``bins``, a chunk at a time;
        returns the number drawn."""
        which = np.repeat(bins, per_bin)
        for start in range(0, which.size, CHUNK):
            self._chunk(which[start:start + CHUNK])
            progress(offset + min(start + CHUNK, which.size))
        return int(which.size)

    def _chunk(self, kk: np.ndarray) -> None:
        n, d = kk.size, self.dims
        self.tried += np.bincount(kk, minlength=self.tried.size)
        lo, hi = self.r_lo[kk] ** d, self.r_hi[kk] ** d
        r = (lo + self.rng.random(n) * (hi - lo)) ** (1.0 / d)
        u = self.rng.normal(size=(n, d))
        u *= (r / np.maximum(np.sqrt((u * u).sum(axis=1)), 1e-300))[:, None]
        h = np.rint(u).astype(np.int64)
        kh = np.floor(np.sqrt((h * h).sum(axis=1).astype(np.float64)) * self.scale + 0.5)
        i = self.rng.integers(0, self.idx.shape[0], n)
        t = np.take(self.idx, i, axis=0) + h
        ok = (kh.astype(np.int64) == kk) & np.all((t >= 0) & (t < self.shape), axis=1)
        i, t, kk = i[ok], t[ok], kk[ok]
        key = np.ravel_multi_index(t.T, tuple(int(s) for s in self.shape))
        if self.bits is not None:  # most proposals miss: test the bitmap first
            on = (self.bits[key >> 3] >> (key & 7).astype(np.uint8)) & 1 == 1
            i, key, kk = i[on], key[on], kk[on]
        at = np.minimum(np.searchsorted(self.keys, key), self.keys.size - 1)
        hit = self.keys[at] == key
        j = self.order[at[hit]]
        self.geo += np.bincount(kk[hit], minlength=self.geo.size)
        self.acc.add(i[hit], j, kk[hit], self.found)

