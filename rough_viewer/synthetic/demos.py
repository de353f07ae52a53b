"""Registry of the demo data sets: names, files, loading and regeneration.

Three demos:

- ``outcrop``: the bundled synthetic Box Canyon-like basalt exposure
  (``demo_data/outcrop.laz``, about 2 M points, with ground truth);
- ``outcrop-small``: a small piece of such an exposure for quick loading
  (``demo_data/outcrop-small.laz``, about 120 k points);
- ``board``: the 2012 paper's hemisphere board, ray-cast on the fly for any
  rotation (``alpha_deg``, ``beta_deg``).

The bundled files live in the repository's top-level ``demo_data/``, installed as
the package data ``rough_viewer.demo_data``: ``pip install .`` and ``pip install
-e .`` both find them. ``python -m rough_viewer.synthetic`` rewrites them byte for
byte.
"""

from __future__ import annotations

import functools
import importlib.resources
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from rough_viewer.io import PointCloud, load_las_with_extra, load_points, write_las
from rough_viewer.synthetic import board as _board
from rough_viewer.synthetic import outcrop as _outcrop
from rough_viewer.vocabulary import InputError


def _demo_dir() -> Path:
    """Folder of the installed package data ``rough_viewer.demo_data``; in a source
    tree that was never installed, ``<repository root>/demo_data``."""
    try:
        return Path(str(importlib.resources.files("rough_viewer.demo_data")))
    except ModuleNotFoundError:
        return Path(__file__).resolve().parents[2] / "demo_data"


#: Folder of the bundled demo files.
DEMO_DIR = _demo_dir()

#: Coordinate resolution of the written demo files (m).
DEMO_SCALE_M = 1e-4


@dataclass(frozen=True)
class DemoInfo:
    """One demo data set."""

    name: str
    """Name used by ``rough-viewer demo`` and ``serve --demo``."""
    description: str
    """One line saying what it is."""
    path: Path | None
    """The bundled file, or None for a demo generated on the fly."""
    kind: Literal["bundled", "generated"]
    """``"bundled"``: a file in ``demo_data/``; ``"generated"``: computed when loaded."""


@dataclass(frozen=True)
class DemoTruth:
    """Ground truth of a demo cloud, aligned point for point with :func:`load_demo`."""

    labels: np.ndarray
    """(N,) uint8 class of each point."""
    names: tuple[str, ...]
    """Class names by value (``names[labels[i]]``)."""
    face: np.ndarray | None
    """(N,) uint8 face part (outcrop demos: main face, curve, turned wall), else None."""
    face_names: tuple[str, ...]
    """Face-part names by value (empty when ``face`` is None)."""


_OUTCROPS: dict[str, tuple[str, _outcrop.OutcropSpec, str]] = {
    "outcrop": (
        "outcrop.laz",
        _outcrop.OUTCROP,
        "synthetic vertical basalt exposure (40 m x 10 m, Box Canyon-like): two flows, "
        "rubbly margin, columnar fractures, a 35-degree bend; ~2 M points with truth",
    ),
    "outcrop-small": (
        "outcrop-small.laz",
        _outcrop.OUTCROP_SMALL,
        "small piece of a synthetic basalt exposure (14 m x 7 m) for quick loading; "
        "~120 k points with truth",
    ),
}

_BOARD_DESCRIPTION = (
    "the 2012 paper's 1 m board with 132 hemispheres (r = 0.019 m), ray-cast from 4.5 m "
    "at 2 mm spacing for any rotation alpha, beta (generated on the fly)"
)


def list_demos() -> list[DemoInfo]:
    """Every demo, bundled ones first."""
    out = [
        DemoInfo(name, desc, DEMO_DIR / fname, "bundled")
        for name, (fname, _, desc) in _OUTCROPS.items()
    ]
    out.append(DemoInfo("board", _BOARD_DESCRIPTION, None, "generated"))
    return out


def _check_name(name: str) -> None:
    names = [d.name for d in list_demos()]
    if name not in names:
        raise InputError(f"unknown demo {name!r}; choose one of: {', '.join(names)}")


def demo_path(name: str) -> Path:
    """The bundled file of demo ``name`` (InputError if unknown, not bundled or missing)."""
    _check_name(name)
    if name not in _OUTCROPS:
        raise InputError(f"demo {name!r} is generated on the fly and has no bundled file")
    p = DEMO_DIR / _OUTCROPS[name][0]
    if not p.is_file():
        raise InputError(
            f"bundled demo file missing: {p} (run `python -m rough_viewer.synthetic`)"
        )
    return p


def load_demo(name: str, *, alpha_deg: float = 0.0, beta_deg: float = 0.0) -> PointCloud:
    """The points of demo ``name``, with the position of the scanner that scanned them
    (``scanner_positions``, ``scan_index``).

    ``alpha_deg`` and ``beta_deg`` choose the board's rotation (degrees; ignored by
    the other demos). Board scans are cached in memory per rotation.
    """
    _check_name(name)
    if name == "board":
        return _board.board_scan(alpha_deg, beta_deg).cloud
    return _with_demo_scanner(name, load_points(demo_path(name)))


def demo_angular_step(name: str) -> float:
    """Angular step of the scanner of demo ``name``, radians (the board: 2 mm at
    4.5 m; the outcrops: their spec's ``angular_step_rad``)."""
    _check_name(name)
    if name == "board":
        return _board.board_scan(0.0, 0.0).angular_step_rad
    return float(_OUTCROPS[name][1].angular_step_rad)


def _with_demo_scanner(name: str, cloud: PointCloud) -> PointCloud:
    """A bundled outcrop's cloud with its spec's scanner position (one scan)."""
    from rough_viewer.scanner.positions import with_scanner

    return with_scanner(cloud, _OUTCROPS[name][1].scanner)


def demo_truth(name: str, *, alpha_deg: float = 0.0, beta_deg: float = 0.0) -> DemoTruth:
    """Ground truth of demo ``name``, aligned with :func:`load_demo`'s points.

    Outcrops: classes rock / column-bounding fracture / column-normal fracture /
    rubble and the face part. Board: flat board (0) or hemisphere (1).
    """
    return load_demo_with_truth(name, alpha_deg=alpha_deg, beta_deg=beta_deg)[1]


def load_demo_with_truth(
    name: str, *, alpha_deg: float = 0.0, beta_deg: float = 0.0
) -> tuple[PointCloud, DemoTruth]:
    """Points and ground truth of demo ``name`` read in one pass (kept in memory).

    Same points, in the same order, as :func:`load_demo`.
    """
    _check_name(name)
    if name == "board":
        scan = _board.board_scan(alpha_deg, beta_deg)
        truth = DemoTruth(scan.on_sphere.astype(np.uint8), ("board", "hemisphere"), None, ())
        return scan.cloud, truth
    p = demo_path(name)
    st = p.stat()
    cloud, truth = _read_bundled(str(p), st.st_size, st.st_mtime_ns)
    return _with_demo_scanner(name, cloud), truth


@functools.lru_cache(maxsize=2)
def _read_bundled(path: str, size: int, mtime_ns: int) -> tuple[PointCloud, DemoTruth]:
    """Points, truth and face part of a bundled outcrop file (cached per file version)."""
    cloud, extra = load_las_with_extra(path, ("truth", "face"), trusted=True)  # bundled
    truth = extra["truth"].astype(np.uint8)
    face = extra["face"].astype(np.uint8)
    return cloud, DemoTruth(truth, _outcrop.TRUTH_NAMES, face, _outcrop.FACE_NAMES)


def write_demo(
    name: str,
    path: str | os.PathLike[str],
    *,
    alpha_deg: float = 0.0,
    beta_deg: float = 0.0,
) -> int:
    """Generate demo ``name`` and write it as LAS/LAZ with its truth; returns the point count.

    The outcrops are written exactly as bundled (same bytes for the same spec). The
    caller checks that ``path`` may be written.
    """
    _check_name(name)
    p = Path(path)
    if p.suffix.lower() not in (".las", ".laz"):
        raise InputError(f"demo output must be .las or .laz: {p}")
    if name == "board":
        board = _board.board_scan(alpha_deg, beta_deg)
        write_las(p, board.cloud, scale=DEMO_SCALE_M,
                  extra={"truth": board.on_sphere.astype(np.uint8)})
        return board.cloud.n
    outcrop = _outcrop.generate_outcrop(_OUTCROPS[name][1])
    write_las(p, outcrop.cloud, scale=DEMO_SCALE_M,
              extra={"truth": outcrop.truth, "face": outcrop.face})
    return outcrop.cloud.n


def regenerate_bundled(out_dir: str | os.PathLike[str] | None = None) -> list[Path]:
    """Rewrite every bundled demo file into ``out_dir`` (default :data:`DEMO_DIR`)."""
    folder = Path(out_dir) if out_dir is not None else DEMO_DIR
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, (fname, _, _) in _OUTCROPS.items():
        write_demo(name, folder / fname)
        paths.append(folder / fname)
    return paths
