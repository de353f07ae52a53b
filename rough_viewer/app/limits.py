"""The app's limits in one place: what one browser, one upload or one long-running
server may cost. Everything the app keeps for long is bounded by one of these.

This module imports nothing, so the command line can read the defaults cheaply.
"""

from __future__ import annotations

#: Largest upload accepted by default, megabytes (``serve --max-upload-mb``).
DEFAULT_MAX_UPLOAD_MB = 2048
#: Uploads received at the same time, at most.
MAX_ACTIVE_UPLOADS = 2
#: Free disk space kept beyond an upload, bytes.
UPLOAD_DISK_MARGIN = 256 << 20
#: Longest upload file name shown, characters.
MAX_UPLOAD_NAME = 200

#: Memory budget of the cached grids of one loaded cloud (grid results and cell
#: membership together), bytes: 1 GiB. Least recently used grids go first.
CACHE_BYTES = 1 << 30

#: Jobs waiting for the worker at once (a flood of clicks is refused beyond).
MAX_PENDING_JOBS = 64
#: Finished jobs whose stage times the worker keeps.
MAX_JOB_RECORDS = 500
#: Error messages the app keeps (``App.errors``).
MAX_ERRORS = 100
#: View timing records the app keeps (``App.timings``).
MAX_TIMINGS = 200
#: Kept profiles in profile mode (the oldest is dropped first).
MAX_PROFILES = 20
#: Refused requests and values kept for diagnostics (gate, controls, uploads).
MAX_REFUSALS = 100

#: Longest text a browser may put in a text field, characters.
MAX_TEXT = 4096
#: Longest message shown to a browser, characters.
MAX_MESSAGE = 300

#: Default display budget (points drawn in the browser).
DEFAULT_MAX_DISPLAY = 2_000_000


#: Bytes the app holds per point of its cloud once prepared (the cloud's columns, the
#: overview sample, the octree, the shown grid's cells, the layers), beside
#: :data:`APP_FIXED_BYTES` and its grid cache (:data:`APP_CACHE_BYTES_PER_POINT`, at
#: most :data:`CACHE_BYTES`). Measured with
#: ``benchmarks/bench_serve_memory.py`` (a synthetic face in a LAZ read as ``serve``
#: does, ``build_app`` until idle, resident memory of the process): 8 M - 4 M points
#: 79 B a point without the idle prefetch, 98 B with it; rounded up to 100.
APP_BYTES_PER_POINT = 100.0
#: Bytes of a ``serve`` process before any cloud: the interpreter, numpy, viser, the
#: app's modules (measured as above: 242 MiB with 500,000 points, less their
#: 50 MB; rounded up to 256 MiB).
APP_FIXED_BYTES = 256 << 20
#: Bytes a point of the grid cache ``serve --memory`` counts, up to :data:`CACHE_BYTES`:
#: the cells of the four preset grids the app computes while idle (a grid's
#: point-to-cell map is 8 bytes a point: 160 MB at 20 M points).
APP_CACHE_BYTES_PER_POINT = 32.0
