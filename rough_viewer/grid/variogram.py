"""Experimental semivariograms of per-cell maps: exact over all pairs of cells where
that fits a time budget, else estimated from a random sample of pairs with a
standard error per lag.

Definition (2011 paper, Fig. 4; docs/science.md section 1)::

    gamma(k) = 1 / (2 N_k) * sum over unordered cell pairs (i, j) in bin k of (Z_i - Z_j)^2

Default binning: distances between cell centres (metres), bin ``k = 1, 2, ..., K``
holds the pairs whose distance ``d`` lies in ``[(k - 0.5) w, (k + 0.5) w)`` with bin
width ``w`` = the cell size ``g``; its lag is ``k w``. Bins run up to half the largest
extent of the map: ``K = floor(max_lag / w)`` with ``max_lag`` = half the longest
side of the bounding box of the occupied cells (``(i_max - i_min + 1) g`` on the
longest axis). With a bin width above ``2 g`` the pairs closer than ``w / 2`` fall in
no bin and are not counted.

Method. Cells sit on a regular grid, so every pair of cells differs by an integer lag
vector ``h``. With the indicator grid ``I`` (1 where a cell has a value) and the value
grid ``Z`` (0 elsewhere), for every lag vector at once::

    N(h) = sum_x I(x) I(x + h)
    S(h) = sum_x I(x) I(x + h) (Z(x + h) - Z(x))^2
         = C[I, Z^2](h) + C[Z^2, I](h) - 2 C[Z, Z](h)

where ``C[A, B](h) = sum_x A(x) B(x + h)`` is a cross-correlation, computed with real
FFTs. Ordered pairs are summed per bin of ``|h| g``; each unordered pair is seen
twice (``h`` and ``-h``), which cancels in ``gamma`` and is divided out of the pair
count. This is exact: the pair counts are whole numbers recovered by rounding, and
``gamma`` equals a brute-force loop over all pairs to round-off (the values are
centred and scaled before the transforms to keep that round-off small).

Memory follows the occupied cells, not the bounding box (tiled FFT). The occupied
cells are cut into cubic blocks of ``B`` cells a side; each occupied block is
correlated with the cells within the largest lag ``r`` (in cells) around it, in an
FFT frame of ``min(B + 2r, S) + r`` cells per axis (``S`` the extent of the map along
that axis): the frame holds every partner of the block's cells at lags up to ``r``,
and its zero margin keeps the circular correlation free of wrap-around. Summed over
the blocks, every ordered pair within ``r`` is counted once. ``B`` is chosen among
powers of two (and the whole extent: one block, the plain FFT of the box) to
minimise the estimated time ``blocks x (frame volume, lag window)`` among the
sizes that fit the memory budget, so a compact map costs one FFT of its box and
two patches far apart cost two small frames, not the box between them.

Few cells spread far apart are cheaper counted directly: every ordered pair, a
chunk of rows at a time (time ``O(M^2)``, memory :data:`PAIR_CHUNK_BYTES` plus
``O(M)``), exact at any lag.

Choice of method (``method="auto"``), by a cost estimate, never by a timing: the
direct count costs ``PAIR_SECONDS x M^2`` (:data:`PAIR_SECONDS_COMPILED` where the
compiled count runs), the tiled FFT its blocks' frame volumes
(:data:`FRAME_SECONDS`, :data:`LAG_SECONDS`; only where its memory fits). The
cheaper runs when its estimate for all the maps of the call fits ``time_budget``
seconds (default :data:`TIME_BUDGET`); beyond, the semivariogram is estimated at the
full lag from a random sample of cell pairs sized to that budget, with a standard
error per bin (:mod:`rough_viewer.grid.variogram_sample`; ``method="sample"``).
``method=`` forces one.

Cost of the FFT: time ``O(blocks x F log F)``, memory ``O(F + W + M)`` with ``F`` the frame
volume (about :data:`BYTES_PER_FRAME_CELL` bytes per frame cell at the peak), ``W =
prod(2 r_a + 1)`` the lag window (:data:`BYTES_PER_LAG` bytes each) and ``M`` the
cells with a value. Both follow the occupied cells and the largest lag, never the
distance between far-apart parts. The estimate is :func:`plan_semivariogram`'s
``bytes``; it is checked with :func:`rough_viewer.memory.require` before anything
large is allocated. With ``method="fft"`` forced and the default ``max_lag`` the
lag is shortened (halved until the estimate fits :data:`MEMORY_BUDGET`, the
available memory and the time budget) and the result says so (``lag_limited``); a
``max_lag`` given explicitly is never shortened, and one that cannot fit is an
InputError.

The face-plane variant (:func:`face_semivariogram`) is the 2-D analogue: cell
centres are projected onto the plane of the face, rasterised at the cell size (the
mean of the cells falling into one pixel), and the same estimator runs on that
2-D grid with distances measured in the plane.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Literal

import numpy as np

from rough_viewer.grid.maps import Plane, face_raster
from rough_viewer.memory import USABLE_SHARE, available_bytes, require
from rough_viewer.vocabulary import InputError, ProgressFn

if TYPE_CHECKING:
    from rough_viewer.grid.variogram_sample import SampledSums

Space = Literal["3d", "plane"]
Method = Literal["auto", "fft", "pairs", "sample"]
Exactness = Literal["fft", "pairs", "sample"]


@dataclass(frozen=True)
class Semivariogram:
    """An experimental semivariogram (all arrays have one entry per lag bin)."""

    lag: np.ndarray
    """(K,) bin centres ``k * bin_width``, metres, k = 1..K."""
    gamma: np.ndarray
    """(K,) semivariance, in the map's units squared (m^2 for roughness); NaN where
    a bin holds no pair."""
    gamma_normalised: np.ndarray
    """(K,) ``gamma / variance`` (sill near 1 for uncorrelated values); NaN where
    the variance is 0 or the bin is empty."""
    pairs: np.ndarray
    """(K,) int64, number of unordered cell pairs in each bin."""
    variance: float
    """Population variance of the map values (divides by the number of cells)."""
    n_cells: int
    """Number of cells with a finite value that entered the estimate."""
    bin_width: float
    """Width of the lag bins, metres."""
    max_lag: float
    """Largest lag asked for, metres (the last bin centre is <= this)."""
    space: Space
    """``"3d"``: distances between cell centres in space; ``"plane"``: distances in
    the plane of the face after projection and rasterisation."""
    lag_limited: bool = False
    """True when the default max lag (half the map's extent) was shortened to fit in
    memory: ``max_lag`` is then the lag actually reached."""
    method: Exactness = "fft"
    """How it was computed: ``"fft"`` (tiled FFT) and ``"pairs"`` (direct count) are
    exact over every pair; ``"sample"`` is an estimate from a random sample of cell
    pairs (:mod:`rough_viewer.grid.variogram_sample`), with ``gamma_se``."""
    gamma_se: np.ndarray | None = None
    """(K,) standard error of ``gamma`` (same unit) for a sampled estimate, NaN where
    a bin has fewer than two sampled pairs; None when exact."""
    sampled: np.ndarray | None = None
    """(K,) int64, sampled pairs that entered each bin's estimate; None when exact
    (``pairs`` is then the exact count; for a sample it is an estimate)."""

    @property
    def exact(self) -> bool:
        """True when every pair entered (not a sampled estimate)."""
        return self.method != "sample"

    @property
    def gamma_normalised_se(self) -> np.ndarray | None:
        """(K,) standard error of ``gamma_normalised`` (the map's variance is taken
        as exact: it is computed over every cell); None when exact."""
        if self.gamma_se is None:
            return None
        if not self.variance > 0:
            return np.full(self.gamma_se.shape, np.nan)
        return self.gamma_se / self.variance


#: Bytes per FFT frame cell at the peak of one block: the real frame, six half
#: spectra (indicator, value, value squared of the block and of its surroundings),
#: the combined spectrum and two inverse transforms.
BYTES_PER_FRAME_CELL = 112
#: Bytes per lag vector of the window: its bin index, mask and the two extracted sums.
BYTES_PER_LAG = 40
#: Bytes per cell with a value: indices, values and per-block selections.
BYTES_PER_CELL = 96
#: Most memory one semivariogram may take when its lag is chosen by default, bytes.
MEMORY_BUDGET = 512 * 2**20
#: Estimated seconds per FFT frame cell and block (eight real transforms), per lag
#: vector and block (extracting and binning the window) and per ordered pair of the
#: direct count (NumPy; compiled on all threads: 1.4-6e-9 measured), on the
#: project's 2-core machine: the cost model that picks the method. ``TIME_BUDGET``:
#: the default seconds of :func:`semivariogram` (``time_budget``).
FRAME_SECONDS = 4.0e-7
LAG_SECONDS = 1.5e-6
PAIR_SECONDS = 1.2e-8
PAIR_SECONDS_COMPILED = 3.0e-9
TIME_BUDGET = 3.0
#: Memory of one chunk of the direct pair count, bytes.
PAIR_CHUNK_BYTES = 32 * 2**20
#: Pairs the compiled direct count takes between two progress calls (a fraction of
#: a second: a cancelled job stops soon).
PAIR_BATCH = 20_000_000


@dataclass(frozen=True)
class VariogramPlan:
    """How a semivariogram will be computed and what it will cost (from
    :func:`plan_semivariogram`)."""

    n_bins: int
    """Lag bins ``k = 1 .. n_bins``."""
    max_lag: float
    """Largest bin centre used, metres (shortened from the default when
    ``lag_limited``)."""
    lag_limited: bool
    """True when the default max lag was shortened to fit memory."""
    reach: tuple[int, ...]
    """Largest lag in cells along each axis that can fall in a bin."""
    block: tuple[int, ...]
    """Block edge in cells along each axis."""
    frame: tuple[int, ...]
    """FFT frame length along each axis."""
    n_blocks: int
    """Occupied blocks (FFT frames computed)."""
    bytes: float
    """Estimated peak memory, bytes."""
    method: Exactness = "fft"
    """``"fft"``: tiled FFT; ``"pairs"``: every pair counted directly, in chunks
    (cheaper for few cells spread far apart); ``"sample"``: estimated from a random
    sample of pairs (when neither exact method fits the time budget)."""
    seconds: float = 0.0
    """Estimated time, seconds (cost model, not a promise), for all the maps
    of the call."""
    samples: int = 0
    """Sampled method: uniformly drawn cell pairs (stage 1)."""
    proposals: int = 0
    """Sampled method: most lag-vector proposals of the short lags (stage 2)."""


@dataclass(frozen=True)
class _Cells:
    """The cells with a value, indices shifted to start at 0."""

    idx: np.ndarray
    """(M, D) int64 indices, minimum 0 per axis."""
    z: np.ndarray
    """(M,) values."""
    shape: tuple[int, ...]
    """Extent of the occupied cells per axis (1 when there are none)."""
    variance: float
    """Population variance of the values (NaN when there are none)."""


def semivariogram(
    ijk: np.ndarray,
    values: np.ndarray,
    cell_size: float,
    *,
    bin_width: float | None = None,
    max_lag: float | None = None,
    space: Space = "3d",
    workers: int | None = None,
    method: Method = "auto",
    time_budget: float | None = None,
    seed: int = 0,
    progress: ProgressFn | None = None,
) -> Semivariogram:
    """Experimental semivariogram of a map on a regular grid: exact over all pairs
    up to the largest lag where the cost model says that fits ``time_budget``
    (tiled FFT or direct count, memory that follows the occupied cells), else
    estimated from a random sample of pairs with a standard error per bin
    (:mod:`rough_viewer.grid.variogram_sample`).

    Parameters
    ----------
    ijk : (M, D) int array, D = 2 or 3
        Integer cell indices (any origin; only differences matter). Each row must be
        a distinct cell.
    values : (M,) float
        The map value of each cell (e.g. roughness in metres); NaN or inf marks a
        missing value (the cell is left out).
    cell_size : float
        Cell edge ``g``, metres; the distance of two cells is ``g * |ijk_a - ijk_b|``.
    bin_width : float, optional
        Width ``w`` of the lag bins, metres; default ``cell_size``. Bin k holds
        distances in ``[(k - 0.5) w, (k + 0.5) w)``.
    max_lag : float, optional
        Largest bin centre, metres; default half the longest side of the bounding
        box of the cells with a value (with ``method="fft"`` or ``"pairs"``
        shortened, ``lag_limited``, when that cannot fit in memory and time). Bins
        ``k = 1 .. floor(max_lag / w)``.
    space : {"3d", "plane"}
        Label stored in the result (say ``"plane"`` when ``ijk`` are face-plane
        pixels); the computation is the same.
    workers : int, optional
        Threads for :mod:`scipy.fft` (default: all cores).
    method : {"auto", "fft", "pairs", "sample"}
        ``"auto"`` (default): the cheaper exact method when its estimated time
        (:data:`FRAME_SECONDS`, :data:`PAIR_SECONDS`; pair count and FFT frame
        volumes, never a timing) fits ``time_budget``, else a sample sized to that
        budget. The others force one.
    time_budget : float, optional
        Seconds of the cost model the computation may take (default
        :data:`TIME_BUDGET`): the limit for an exact method under ``"auto"`` and
        the size of a sample.
    seed : int
        Seed of a sample's random draws (the same seed, cells and budget give the
        same estimate).
    progress : callable, optional
        ``progress(done, total)``, called before the first and after every FFT
        block (chunk of pair rows, chunk of sampled pairs) and once at the end. An
        exception it raises stops the computation and propagates (how a caller
        cancels: the app's jobs raise from it).

    Returns
    -------
    Semivariogram
        With no bins (K = 0) when fewer than two cells have a value; ``method``
        says how it was computed (``gamma_se`` for a sample).

    Raises
    ------
    InputError
        Bad arguments, or an explicit ``max_lag`` whose computation cannot fit in
        the available memory.
    """
    return semivariograms(ijk, {"map": values}, cell_size, bin_width=bin_width,
                          max_lag=max_lag, space=space, workers=workers, method=method,
                          time_budget=time_budget, seed=seed, progress=progress)["map"]


def semivariograms(
    ijk: np.ndarray,
    maps: Mapping[str, np.ndarray],
    cell_size: float,
    *,
    bin_width: float | None = None,
    max_lag: float | None = None,
    space: Space = "3d",
    workers: int | None = None,
    method: Method = "auto",
    time_budget: float | None = None,
    seed: int = 0,
    progress: ProgressFn | None = None,
) -> dict[str, Semivariogram]:
    """The semivariogram of several maps of one grid (same cells, values per map),
    as :func:`semivariogram` for each, with one choice of method for all of them
    (``time_budget`` covers them all) and, for a sample, the same drawn pairs."""
    if not maps:
        return {}
    g, w = _check_sizes(cell_size, bin_width)
    union = _all_cells(ijk)
    for v in maps.values():
        if np.shape(v) != (union.idx.shape[0],):
            raise ValueError(f"values must have shape ({union.idx.shape[0]},), "
                             f"got {np.shape(v)}")
    budget = TIME_BUDGET if time_budget is None else float(time_budget)
    plan = _plan(union, g, w, max_lag, method, n_maps=len(maps), time_budget=budget)
    if plan.method == "sample":
        return _sampled(union, maps, plan, g, w, space, max_lag, seed, progress)
    out: dict[str, Semivariogram] = {}
    for name, v in maps.items():
        cells = _finite_cells(ijk, v)
        own = _plan(cells, g, w, max_lag, plan.method, time_budget=budget)
        out[name] = _exact(cells, own, g, w, space, workers, progress)
    return out


def plan_semivariogram(
    ijk: np.ndarray,
    values: np.ndarray,
    cell_size: float,
    *,
    bin_width: float | None = None,
    max_lag: float | None = None,
    method: Method = "auto",
    time_budget: float | None = None,
    n_maps: int = 1,
) -> VariogramPlan:
    """The plan :func:`semivariogram` would follow for these arguments (for
    ``n_maps`` maps of these cells, as :func:`semivariograms`): the method, bins,
    the (possibly shortened) max lag, blocks, FFT frame or sample sizes, and the
    estimated peak memory (bytes) and time (seconds). Cheap: no transform is
    computed, no pair drawn."""
    g, w = _check_sizes(cell_size, bin_width)
    cells = _finite_cells(ijk, values)
    budget = TIME_BUDGET if time_budget is None else float(time_budget)
    return _plan(cells, g, w, max_lag, method, n_maps=n_maps, time_budget=budget)


def _exact(cells: _Cells, plan: VariogramPlan, g: float, w: float, space: Space,
           workers: int | None, progress: ProgressFn | None) -> Semivariogram:
    """One map's semivariogram by the plan's exact method."""
    if plan.n_bins <= 0:
        return _assemble(cells, plan, w, space, np.zeros(0), np.zeros(0))
    require(plan.bytes, f"the semivariogram of {cells.z.size:,} cells at {g:g} m up to "
            f"lag {plan.max_lag:g} m", hint="give a smaller max lag or a larger grid size")
    if plan.method == "pairs":
        ordered, sums = _pair_sums(cells, plan, g, w, progress)
    else:
        ordered, sums = _lag_sums(cells, plan, g, w, workers, progress)
    return _assemble(cells, plan, w, space, ordered, sums)


def _sampled(union: _Cells, maps: Mapping[str, np.ndarray], plan: VariogramPlan, g: float, w: float, space: Space,
             max_lag: float | None, seed: int,
             progress: ProgressFn | None) -> dict[str, Semivariogram]:
    """Every map's semivariogram estimated from one sample of pairs of the grid's
    cells (each map truncated to its own bins)."""
    from rough_viewer.grid.variogram_sample import sampled_sums

    require(plan.bytes, f"the sampled semivariogram of {union.z.size:,} cells",
            hint="choose a larger grid size")
    zs, stats = [], []
    for v in maps.values():
        z = np.asarray(v, dtype=np.float64)
        ok = np.isfinite(z)
        zs.append(np.where(ok, z, np.nan))
        n = int(np.count_nonzero(ok))
        extent = 1 if n == 0 else max(union.shape) if n == ok.size else max(
            int(c.max(where=ok, initial=0)) - int(c.min(where=ok, initial=2**62)) + 1
            for c in union.idx.T)
        stats.append((n, float(np.var(z[ok])) if n else float("nan"), extent))
    sums = sampled_sums(union.idx, union.shape, zs, plan.n_bins, g / w, plan.samples,
                        plan.proposals, seed=seed, progress=progress)
    out: dict[str, Semivariogram] = {}
    for name, got, (n, variance, extent) in zip(maps, sums, stats, strict=True):
        lag = float(max_lag) if max_lag is not None else 0.5 * extent * g
        n_bins = min(plan.n_bins, int(np.floor(lag / w + 1e-9)) if n >= 2 else 0)
        out[name] = _assemble_sample(n, variance, n_bins, lag, w, space, got)
    return out


def _assemble_sample(n_cells: int, variance: float, k: int, max_lag: float, w: float,
                     space: Space, got: SampledSums) -> Semivariogram:
    """gamma, its standard error, the estimated pair counts and the normalised
    curve of a sampled estimate (first ``k`` bins)."""
    n, s1, s2 = got.n[:k], got.s1[:k], got.s2[:k]
    with np.errstate(invalid="ignore", divide="ignore"):
        gamma = np.where(n > 0, s1 / n, np.nan)
        var = np.maximum(s2 - s1 * gamma, 0.0) / (n - 1)
        se = np.where(n > 1, np.sqrt(var / n), np.nan)
        gamma_normalised = gamma / variance if variance > 0 else np.full(k, np.nan)
    return Semivariogram(
        lag=np.arange(1, k + 1) * w, gamma=gamma, gamma_normalised=gamma_normalised,
        pairs=np.rint(got.pairs[:k]).astype(np.int64), variance=variance,
        n_cells=n_cells, bin_width=w, max_lag=float(max_lag), space=space,
        method="sample", gamma_se=se, sampled=n.astype(np.int64))


# ----------------------------------------------------------------------------- stages


def _finite_cells(ijk: np.ndarray, values: np.ndarray) -> _Cells:
    """Stage 1: check the arguments, keep the cells with a finite value."""
    ijk = np.asarray(ijk)
    values = np.asarray(values, dtype=np.float64)
    if ijk.ndim != 2 or ijk.shape[1] not in (2, 3):
        raise ValueError(f"ijk must have shape (M, 2) or (M, 3), got {ijk.shape}")
    if values.shape != (ijk.shape[0],):
        raise ValueError(f"values must have shape ({ijk.shape[0]},), got {values.shape}")
    if not np.issubdtype(ijk.dtype, np.integer):
        raise ValueError("ijk must be an integer array of cell indices")
    ok = np.isfinite(values)
    every = bool(ok.all())
    idx = ijk.astype(np.int64) if every else ijk[ok].astype(np.int64)
    z = values if every else values[ok]
    if z.size:
        cols = [idx[:, a] for a in range(idx.shape[1])]
        idx -= np.array([c.min() for c in cols])
        shape = tuple(int(c.max()) + 1 for c in cols)
    else:
        shape = (1,) * ijk.shape[1]
    variance = float(np.var(z)) if z.size else float("nan")
    return _Cells(idx=idx, z=z, shape=shape, variance=variance)


def _check_sizes(cell_size: float, bin_width: float | None) -> tuple[float, float]:
    g = float(cell_size)
    if not g > 0:
        raise InputError(f"cell_size must be positive, got {cell_size}")
    w = g if bin_width is None else float(bin_width)
    if not w > 0:
        raise InputError(f"bin_width must be positive, got {bin_width}")
    return g, w


def _all_cells(ijk: np.ndarray) -> _Cells:
    """Every row of ``ijk`` as a cell (the geometry several maps share)."""
    ijk = np.asarray(ijk)
    return _finite_cells(ijk, np.zeros(ijk.shape[0]) if ijk.ndim == 2 else np.zeros(0))


def _memory_budget() -> float:
    budget = float(MEMORY_BUDGET)
    avail = available_bytes()
    if avail is not None:
        budget = min(budget, USABLE_SHARE * avail)
    return budget


def _plan(cells: _Cells, g: float, w: float, max_lag: float | None,
          method: Method = "auto", *, n_maps: int = 1,
          time_budget: float = 0.0) -> VariogramPlan:
    """Stage 2: bins and the method, with its memory and time estimates.

    ``"auto"``: the cheaper exact method (direct count: ``PAIR_SECONDS x M^2``;
    tiled FFT: :func:`_blocks`' frame volumes, only where its memory fits) when
    its estimate for ``n_maps`` maps is at most ``time_budget`` seconds, else a
    sample sized to ``time_budget``; the lag is never shortened."""
    if method in ("fft", "pairs"):
        return _exact_plan(cells, g, w, max_lag, method, time_budget or TIME_BUDGET)
    lag = float(max_lag) if max_lag is not None else 0.5 * max(cells.shape) * g
    m = int(cells.z.size)
    n_bins = int(np.floor(lag / w + 1e-9)) if m >= 2 else 0
    if n_bins <= 0:
        return VariogramPlan(n_bins=0, max_lag=lag, lag_limited=False, reach=(),
                             block=(), frame=(), n_blocks=0, bytes=0.0)
    if method == "auto":
        best = _cheapest_exact(cells, g, w, n_bins, lag, n_maps, time_budget)
        if best is not None and best.seconds <= time_budget:
            return best
    from rough_viewer.grid.variogram_sample import sample_bytes, sample_seconds, sample_sizes

    samples, proposals = sample_sizes(time_budget, n_maps, m)
    return VariogramPlan(n_bins=n_bins, max_lag=lag, lag_limited=False, reach=(), block=(),
                         frame=(), n_blocks=0, bytes=sample_bytes(m, n_maps), method="sample",
                         seconds=sample_seconds(samples, proposals, n_maps, m),
                         samples=samples, proposals=proposals)


def _pair_seconds(m: int, n_maps: int, time_budget: float) -> float:
    """Cost-model seconds of the direct count of ``n_maps`` maps of ``m`` cells:
    :data:`PAIR_SECONDS_COMPILED` a pair where the compiled count will run (asked
    only when that rate could fit ``time_budget``: asking may load the kernels,
    which the count would load anyway), else :data:`PAIR_SECONDS`."""
    ordered = float(m) * max(m - 1, 0) * n_maps
    if PAIR_SECONDS_COMPILED * ordered <= time_budget:
        from rough_viewer.grid import fast

        if fast.resolve_engine("auto", n_points=m * m) == "numba":
            return PAIR_SECONDS_COMPILED * ordered
    return PAIR_SECONDS * ordered


def _cheapest_exact(cells: _Cells, g: float, w: float, n_bins: int, lag: float,
                    n_maps: int, time_budget: float) -> VariogramPlan | None:
    """The cheaper exact plan at the full lag for ``n_maps`` maps (seconds for all
    of them), or None when neither can fit ``time_budget``. The FFT's blocks are
    only planned when a lower bound of its cost (its lag window once, every cell
    in a frame) is below the direct count's and the budget."""
    m = int(cells.z.size)
    budget = _memory_budget()
    pairs_s = _pair_seconds(m, n_maps, time_budget)
    pairs = VariogramPlan(n_bins=n_bins, max_lag=lag, lag_limited=False, reach=(),
                          block=(), frame=(), n_blocks=0,
                          bytes=PAIR_CHUNK_BYTES + BYTES_PER_CELL * m, method="pairs",
                          seconds=pairs_s)
    reach_all = int(np.floor((n_bins + 0.5) * w / g))
    window = float(np.prod([2 * min(s - 1, reach_all) + 1 for s in cells.shape]))
    floor_s = n_maps * (FRAME_SECONDS * m + LAG_SECONDS * window)
    if floor_s >= pairs_s:
        return pairs if pairs_s <= time_budget else None
    if floor_s > time_budget:
        return None
    fft = _blocks(cells, g, w, n_bins, lag, False, budget)
    fft = replace(fft, seconds=fft.seconds * n_maps)
    if fft.bytes <= budget and fft.seconds < pairs_s:
        return fft
    return pairs


def _exact_plan(cells: _Cells, g: float, w: float, max_lag: float | None,
                method: Literal["fft", "pairs"], time_budget: float) -> VariogramPlan:
    """Stage 2 of a forced exact method: bins and the memory estimate; with the
    default max lag, the FFT's lag halved until it fits the memory budget and
    ``time_budget`` (unless the direct count is asked for)."""
    explicit = max_lag is not None
    lag = float(max_lag) if max_lag is not None else 0.5 * max(cells.shape) * g
    m = int(cells.z.size)
    limited = False
    budget = _memory_budget()
    pair_seconds = PAIR_SECONDS * m * max(m - 1, 0)
    while True:
        n_bins = int(np.floor(lag / w + 1e-9)) if m >= 2 else 0
        if n_bins <= 0:
            return VariogramPlan(n_bins=0, max_lag=lag, lag_limited=limited, reach=(),
                                 block=(), frame=(), n_blocks=0, bytes=0.0)
        if method == "pairs":
            return VariogramPlan(n_bins=n_bins, max_lag=lag, lag_limited=False, reach=(),
                                 block=(), frame=(), n_blocks=0, method="pairs",
                                 bytes=PAIR_CHUNK_BYTES + BYTES_PER_CELL * m,
                                 seconds=pair_seconds)
        plan = _blocks(cells, g, w, n_bins, lag, limited, budget)
        fits = plan.bytes <= budget and plan.seconds <= time_budget
        if explicit or fits or n_bins == 1:
            return plan
        lag = max(w, 0.5 * lag)
        limited = True


def _blocks(cells: _Cells, g: float, w: float, n_bins: int, lag: float,
            limited: bool, budget: float = np.inf) -> VariogramPlan:
    """The block edge (a power of two or the whole extent) that minimises the
    estimated time ``blocks x (frame volume, lag window)`` for this reach among those
    whose memory estimate fits ``budget`` bytes (the cheapest overall when none fits)."""
    import scipy.fft  # here, not on import: loading it costs 0.2 s of every command's start

    reach_all = int(np.floor((n_bins + 0.5) * w / g))
    reach = tuple(min(s - 1, reach_all) for s in cells.shape)
    window = float(np.prod([2 * r + 1 for r in reach]))
    longest = max(cells.shape)
    sizes = sorted({*(1 << k for k in range(2, max(2, longest.bit_length()) + 1)), longest})
    best: VariogramPlan | None = None
    best_cost = np.inf
    best_fits = False
    for b in sizes:
        block = tuple(min(b, s) for s in cells.shape)
        frame = tuple(
            scipy.fft.next_fast_len(min(bl + 2 * r, s) + r, real=True)
            for bl, r, s in zip(block, reach, cells.shape, strict=True)
        )
        n_blocks = _count_blocks(cells, block)
        volume = float(np.prod(frame))
        cost = n_blocks * (FRAME_SECONDS * volume + LAG_SECONDS * window)
        est = BYTES_PER_FRAME_CELL * volume + BYTES_PER_LAG * window + BYTES_PER_CELL * cells.z.size
        fits = est <= budget
        if (fits and not best_fits) or (fits == best_fits and cost < best_cost):
            best_cost, best_fits = cost, fits
            best = VariogramPlan(n_bins=n_bins, max_lag=lag, lag_limited=limited, reach=reach,
                                 block=block, frame=frame, n_blocks=n_blocks, bytes=est,
                                 seconds=cost)
    assert best is not None
    return best


def _count_blocks(cells: _Cells, block: tuple[int, ...]) -> int:
    """Occupied blocks of edge ``block`` (cells)."""
    grid = tuple(-(-s // b) for s, b in zip(cells.shape, block, strict=True))
    keys = np.ravel_multi_index((cells.idx // np.array(block)).T, grid)
    return int(np.unique(keys).size)


def _lag_sums(cells: _Cells, plan: VariogramPlan, g: float, w: float,
              workers: int | None,
              progress: ProgressFn | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Stage 3: ordered pair counts and sums of squared differences per lag bin,
    block by block (tiled FFT cross-correlations); ``progress(done, blocks)``
    before the first block and after each."""
    import scipy.fft  # here, not on import (see _blocks)

    n_bins = plan.n_bins
    reach = np.array(plan.reach)
    block = np.array(plan.block)
    shape = np.array(cells.shape)
    frame = plan.frame
    axes = tuple(range(len(frame)))
    # Centre and scale so that the FFT round-off is small relative to the differences.
    scale = float(np.std(cells.z)) or 1.0
    zc = (cells.z - cells.z.mean()) / scale
    # Lag window -reach..reach per axis (negative lags wrap around) and its bins.
    window = np.ix_(*[np.r_[0 : r + 1, -r:0] for r in plan.reach])
    offsets = np.ix_(*[np.r_[0 : r + 1, -r:0].astype(np.float64) for r in plan.reach])
    k = np.floor(np.sqrt(sum(o * o for o in offsets)) * (g / w) + 0.5).astype(np.int64)
    keep = (k >= 1) & (k <= n_bins)
    kb = k[keep]
    del k
    ordered = np.zeros(n_bins)
    sums = np.zeros(n_bins)

    def spectrum(where: np.ndarray, weights: np.ndarray | None) -> np.ndarray:
        grid = np.zeros(frame)
        grid.flat[where] = 1.0 if weights is None else weights
        return scipy.fft.rfftn(grid, s=frame, axes=axes, workers=workers)

    def back(spec: np.ndarray) -> np.ndarray:
        return scipy.fft.irfftn(spec, s=frame, axes=axes, workers=workers)[window][keep]

    block_of = cells.idx // block
    blocks = np.unique(block_of, axis=0)
    if progress is not None:
        progress(0, len(blocks))
    for done, b in enumerate(blocks, start=1):
        lo = np.maximum(b * block - reach, 0)       # frame origin (cells)
        hi = np.minimum((b + 1) * block + reach, shape)
        inside = np.all(block_of == b, axis=1)
        around = np.all((cells.idx >= lo) & (cells.idx < hi), axis=1)
        a_flat = np.ravel_multi_index((cells.idx[inside] - lo).T, frame)
        e_flat = np.ravel_multi_index((cells.idx[around] - lo).T, frame)
        za, ze = zc[inside], zc[around]
        fa_i, fe_i = spectrum(a_flat, None), spectrum(e_flat, None)
        ordered += np.bincount(kb, weights=np.rint(back(fa_i.conj() * fe_i)),
                               minlength=n_bins + 1)[1:]
        # S = C[I_A, Z2_E] + C[Z2_A, I_E] - 2 C[Z_A, Z_E]
        cross = spectrum(a_flat, za * za).conj() * fe_i
        del fe_i
        cross += fa_i.conj() * spectrum(e_flat, ze * ze)
        del fa_i
        cross -= 2.0 * spectrum(a_flat, za).conj() * spectrum(e_flat, ze)
        sums += np.bincount(kb, weights=back(cross), minlength=n_bins + 1)[1:]
        del cross
        if progress is not None:
            progress(done, len(blocks))
    return ordered, sums * scale * scale


def _pair_sums(cells: _Cells, plan: VariogramPlan, g: float, w: float,
               progress: ProgressFn | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Stage 3 for few, scattered cells: every ordered pair counted directly, a
    chunk of rows at a time (memory :data:`PAIR_CHUNK_BYTES`); ``progress(rows
    done, rows)`` before the first chunk and after each."""
    from rough_viewer.grid import fast

    n_bins = plan.n_bins
    m = int(cells.z.size)
    pos = cells.idx.astype(np.float64)
    z = cells.z - cells.z.mean()
    rows = max(1, int(PAIR_CHUNK_BYTES // (48 * max(m, 1))))
    ordered = np.zeros(n_bins + 1)
    sums = np.zeros(n_bins + 1)
    if progress is not None:
        progress(0, m)
    if fast.resolve_engine("auto", n_points=m * m) == "numba":
        # the same chunks, pairs and additions in the same order (bit for bit), a
        # batch of about PAIR_BATCH pairs at a time on all threads; the batch's
        # chunks are reported done (and a raising callback stops) after each batch
        n_chunks = -(-m // rows)
        batch = max(1, PAIR_BATCH // (rows * m))
        for first in range(0, n_chunks, batch):
            last = min(n_chunks, first + batch)
            counts, parts = fast.pair_sums(pos, z, g / w, n_bins, rows, first, last)
            for c in range(last - first):
                ordered += counts[c]
                sums += parts[c]
                if progress is not None:
                    progress(min(m, (first + c + 1) * rows), m)
        return ordered[1:], sums[1:]
    for start in range(0, m, rows):
        sl = slice(start, min(start + rows, m))
        d2 = np.zeros((sl.stop - sl.start, m))
        for a in range(pos.shape[1]):
            d2 += (pos[sl, a, None] - pos[None, :, a]) ** 2
        k = np.floor(np.sqrt(d2) * (g / w) + 0.5).astype(np.int64)
        del d2
        keep = (k >= 1) & (k <= n_bins)
        diff2 = (z[sl, None] - z[None, :]) ** 2
        ordered += np.bincount(k[keep], minlength=n_bins + 1)
        sums += np.bincount(k[keep], weights=diff2[keep], minlength=n_bins + 1)
        if progress is not None:
            progress(sl.stop, m)
    return ordered[1:], sums[1:]


def _assemble(cells: _Cells, plan: VariogramPlan, w: float, space: Space,
              ordered: np.ndarray, sums: np.ndarray) -> Semivariogram:
    """Stage 4: gamma, pair counts and the normalised curve."""
    n_bins = plan.n_bins
    pairs = np.rint(ordered / 2.0).astype(np.int64)
    with np.errstate(invalid="ignore", divide="ignore"):
        gamma = np.where(ordered > 0, np.maximum(sums, 0.0) / (2.0 * ordered), np.nan)
        gamma_normalised = (gamma / cells.variance if cells.variance > 0
                            else np.full(n_bins, np.nan))
    return Semivariogram(
        lag=np.arange(1, n_bins + 1) * w,
        gamma=gamma,
        gamma_normalised=gamma_normalised,
        pairs=pairs,
        variance=cells.variance,
        n_cells=int(cells.z.size),
        bin_width=w,
        max_lag=float(plan.max_lag),
        space=space,
        lag_limited=plan.lag_limited,
        method="pairs" if plan.method == "pairs" else "fft",
    )


def sampling_note(variograms: Iterable[Semivariogram], *, prefix: str = "") -> str:
    """How the semivariograms were computed, for a subtitle or a report: empty when
    all are exact over every pair, else the sampled pairs and what the bars mean."""
    sampled = [vg.sampled for vg in variograms if not vg.exact and vg.sampled is not None]
    if not sampled:
        return ""
    least = min(int(n.min()) if n.size else 0 for n in sampled)
    most = max(int(n.sum()) for n in sampled)
    return (f"{prefix}estimated from a random sample of {most:,} cell pairs (at least "
            f"{least:,} a lag), bars ±1 standard error")


def face_semivariogram(
    centres: np.ndarray,
    values: np.ndarray,
    cell_size: float,
    plane: Plane,
    *,
    bin_width: float | None = None,
    max_lag: float | None = None,
    workers: int | None = None,
    time_budget: float | None = None,
    seed: int = 0,
    progress: ProgressFn | None = None,
) -> Semivariogram:
    """Semivariogram in the plane of the face (the 2-D analogue of :func:`semivariogram`).

    Cell centres are projected onto the 2-D axes of ``plane`` (see
    :func:`rough_viewer.grid.maps.face_raster`) and rasterised at ``cell_size``; where
    several cells fall into one pixel their values are averaged. The estimator then
    runs on the 2-D pixel grid, distances in the plane.

    Parameters
    ----------
    centres : (M, 3) float
        Cell centres, metres.
    values : (M,) float
        Map values; NaN = missing (left out before rasterising).
    cell_size : float
        Cell edge and pixel size, metres.
    plane : Plane
        Anything with ``centroid`` (3,) and unit ``normal`` (3,), e.g. the whole-cloud
        ODR plane (:class:`rough_viewer.grid.planes.PlaneFit`).
    bin_width, max_lag, workers, time_budget, seed, progress
        As for :func:`semivariogram` (exact or sampled by the same cost model).
    """
    values = np.asarray(values, dtype=np.float64)
    ok = np.isfinite(values)
    raster = face_raster(np.asarray(centres, dtype=np.float64)[ok], plane, cell_size)
    pix, inverse = np.unique(raster.pixel, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    total = np.bincount(inverse, weights=values[ok], minlength=len(pix))
    count = np.bincount(inverse, minlength=len(pix))
    mean = total / np.maximum(count, 1)
    return semivariogram(
        pix, mean, cell_size, bin_width=bin_width, max_lag=max_lag, space="plane",
        workers=workers, time_budget=time_budget, seed=seed, progress=progress,
    )
