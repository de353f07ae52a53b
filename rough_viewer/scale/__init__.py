"""Campaign scale: the grid pipeline over many files and clouds larger than memory.

- :mod:`.sources`: the files of one merged cloud, their headers, chunks of points.
- :mod:`.passes`: the two passes (moments, distances) on one chunk, using the grid's
  own code.
- :mod:`.partials`: per-cell sums and their reduction by addition.
- :mod:`.chunked`: the driver (:func:`chunked_roughness`), sequential and
  out of core under a memory budget.
- :mod:`.dask_runner`: the same chunk map and reduction as a Dask graph (optional
  dependency ``rough_viewer[dask]``).
"""

from rough_viewer.scale.chunked import (
    SequentialRunner,
    chunk_points_for,
    chunked_roughness,
    parse_bytes,
)
from rough_viewer.scale.sources import Chunk, Source, chunk_plan, open_sources, read_chunk

__all__ = [
    "Chunk",
    "SequentialRunner",
    "Source",
    "chunk_plan",
    "chunk_points_for",
    "chunked_roughness",
    "open_sources",
    "parse_bytes",
    "read_chunk",
]
