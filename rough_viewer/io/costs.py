"""Each reader's peak memory per point and per byte of file, measured by
``benchmarks/bench_read_memory.py`` (the checks of :mod:`rough_viewer.io.estimates`
and the readers' own use them). Imports nothing of the package, so every reader can.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ReadCost:
    """Peak memory of one reader: ``per_byte * file bytes + per_point * points``
    above the interpreter's own."""

    per_byte: float
    """Bytes per byte of file (buffers, text)."""
    per_point: float
    """Bytes per point read (decoded records, the columns, the finite-row filter)."""
    worst_per_byte: float = 0.0
    """Bytes per byte of file for the worst shape of file measured (text: one long
    line); 0 when the shape does not matter."""


#: Measured peaks (``benchmarks/bench_read_memory.py --points 1000000``: the largest
#: peak per point of the formats' shapes, rounded up; the worst per byte is a text
#: line of 3 million single digits; see docs/robustness.md for the table). A text
#: cloud's points are bounded by its size (one per :data:`MIN_TEXT_ROW` bytes).
COSTS: dict[str, ReadCost] = {
    "las": ReadCost(per_byte=0.0, per_point=72.0),
    "laz": ReadCost(per_byte=0.0, per_point=90.0),
    "e57": ReadCost(per_byte=0.0, per_point=118.0),
    "text": ReadCost(per_byte=0.0, per_point=52.0, worst_per_byte=20.0),
    "ply-ascii": ReadCost(per_byte=0.0, per_point=52.0, worst_per_byte=20.0),
    "ply-binary": ReadCost(per_byte=0.0, per_point=50.0),
    "stl-ascii": ReadCost(per_byte=0.0, per_point=90.0),
    "stl-binary": ReadCost(per_byte=0.0, per_point=94.0),
    "npy": ReadCost(per_byte=0.0, per_point=52.0),
}

__all__ = ["COSTS", "ReadCost"]
