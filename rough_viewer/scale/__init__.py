"""Campaign scale: the grid pipeline over many files and clouds larger than memory.

- :mod:`.sources`: the files of one merged cloud, their headers, chunks of points.
- :mod:`.passes`: the two passes (moments, distances) on one chunk, using the grid's
  own code.
- :mod:`.partials`: per-cell sums and their reduction by addition.
- :mod:`.chunked`: the driver (:func:`chunked_roughness`), sequential and
  out of core under a memory budget.
- :mod:`.dask_runner`: the same chunk map and reduction as a Dask graph (optional
  dependency ``rough_viewer[dask]``).

Names are loaded on first use (a run in memory imports none of the chunked driver).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rough_viewer.lazy import lazy_names

#: Public name -> module that defines it (loaded on first use, PEP 562).
_API: dict[str, str] = {
    "SequentialRunner": "rough_viewer.scale.chunked",
    "chunk_points_for": "rough_viewer.scale.chunked",
    "chunked_roughness": "rough_viewer.scale.chunked",
    "parse_bytes": "rough_viewer.scale.chunked",
    "Chunk": "rough_viewer.scale.sources",
    "Source": "rough_viewer.scale.sources",
    "chunk_plan": "rough_viewer.scale.sources",
    "open_sources": "rough_viewer.scale.sources",
    "read_chunk": "rough_viewer.scale.sources",
}

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


__getattr__, __dir__ = lazy_names(__name__, _API)


if TYPE_CHECKING:  # names for type checkers and IDEs; loaded lazily at run time
    from rough_viewer.scale.chunked import (
        SequentialRunner,
        chunk_points_for,
        chunked_roughness,
        parse_bytes,
    )
    from rough_viewer.scale.sources import Chunk, Source, chunk_plan, open_sources, read_chunk
