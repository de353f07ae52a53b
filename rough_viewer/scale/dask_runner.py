"""The chunk map and the per-cell reduction as a Dask graph (optional dependency
``rough_viewer[dask]``).

The graph of one pass: one task per chunk (``rv-map-<pass>-<i>``: read the chunk
with :func:`~rough_viewer.scale.sources.read_chunk`, run the pass on it), then one
binary tree of merge tasks (``rv-merge-*``, each adding its two subtrees' tables grid
by grid with :func:`~rough_viewer.scale.partials.merge`): per grid the same tree as
:func:`~rough_viewer.scale.partials.reduce_partials` (chunk order), so the result
is the same bits for any number of workers and any order of completion. The pass's
parameters (grids, and in pass 2 the per-cell planes) are one key of the
graph (a distributed scheduler sends it once to each worker).

Schedulers:

- ``"threads"``, ``"processes"``: Dask's local schedulers in this process (a thread
  pool, or one pool of worker processes kept for both passes). Decoding LAZ holds
  Python's GIL, so threads add little speed; processes do;
- ``"tcp://HOST:PORT"`` (or any ``dask.distributed`` address): an existing
  scheduler through a ``distributed.Client``; tasks of a worker that dies are run
  again elsewhere by Dask (up to its ``allowed-failures``), with the same result.
  Every worker must be able to read the input paths.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from rough_viewer.scale.chunked import ChunkDone, ChunkTask
from rough_viewer.scale.partials import Partial, merge
from rough_viewer.scale.sources import Chunk, Source, chunk_plan, read_chunk
from rough_viewer.vocabulary import InputError, error_line

_RUN = itertools.count()


def _map_chunk(source: Source, chunk: Chunk, task: ChunkTask) -> list[Partial]:
    single = getattr(task, "threads", 0) == 1
    x, y, z = read_chunk(source, chunk, parallel=not single)
    return task(x, y, z)


def _pick(parts: list[Partial], i: int) -> Partial:
    return parts[i]


def _merge_lists(a: list[Partial], b: list[Partial]) -> list[Partial]:
    """Output by output, ``merge(a[g], b[g])``: the same additions as one tree per output."""
    return [merge(x, y) for x, y in zip(a, b, strict=True)]


def _one_thread() -> None:
    """Start of a pool process: its tasks run on one thread (:attr:`DaskRunner.inner_threads`),
    so numba need not start a thread per core in each of the pool's processes."""
    import os

    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    os.environ.setdefault("RAYON_NUM_THREADS", "1")  # lazrs's decoding of a COPC tile


#: Largest first message of a Dask scheduler's handshake :func:`probe_scheduler` takes.
MAX_HANDSHAKE_BYTES = 1 << 20


def probe_scheduler(address: str, timeout: float = 10.0) -> None:
    """Check that a ``tcp://HOST:PORT`` address answers as a Dask scheduler before
    ``distributed.Client`` connects to it: the scheduler writes its handshake as soon
    as a connection opens (an 8-byte length, then that many bytes). A server that
    sends nothing (an HTTP server waiting for a request: the client would wait for
    ever) or sends something else (read as a length, an exabyte allocation) is
    refused in one line. Other protocols (``tls://``, ``inproc://``) are left to
    ``distributed``.

    Raises
    ------
    InputError
        Nothing listens there, nothing answers within ``timeout`` seconds, or the
        answer is not a Dask handshake.
    """
    import socket
    import struct
    from urllib.parse import urlsplit

    if not address.startswith("tcp://"):
        return
    try:
        parts = urlsplit(address)
        host, port = parts.hostname, parts.port
    except ValueError:
        host, port = None, None
    if not host or port is None:
        raise InputError(f"--scheduler expects tcp://HOST:PORT, got {address!r}")
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except TimeoutError:
        raise InputError(f"cannot reach the Dask scheduler at {address}: no connection "
                         f"within {timeout:g} s") from None
    except OSError as exc:
        raise InputError(f"cannot reach the Dask scheduler at {address}: "
                         f"{exc.strerror or type(exc).__name__}") from None
    head = b""
    with sock:
        try:
            sock.settimeout(timeout)
            while len(head) < 8:
                part = sock.recv(8 - len(head))
                if not part:
                    break
                head += part
        except TimeoutError:
            raise InputError(f"{address} did not answer as a Dask scheduler within "
                             f"{timeout:g} s (is it another kind of server?)") from None
        except OSError as exc:
            raise InputError(f"{address} closed the connection: "
                             f"{exc.strerror or type(exc).__name__}") from None
    size = struct.unpack("<Q", head)[0] if len(head) == 8 else 0
    if not 8 <= size <= MAX_HANDSHAKE_BYTES:
        raise InputError(f"{address} answered, but not as a Dask scheduler")


def _import_dask() -> Any:
    try:
        import dask
    except ImportError:
        raise InputError("--scheduler needs Dask: pip install 'rough_viewer[dask]'") from None
    return dask


class DaskRunner:
    """Runs the passes on a Dask scheduler.

    Parameters
    ----------
    scheduler : str
        ``"threads"``, ``"processes"`` or the address of a ``dask.distributed``
        scheduler (``"tcp://127.0.0.1:8786"``).
    workers : int, optional
        Threads or processes of a local scheduler (default: Dask's, the CPU count).
    client : distributed.Client, optional
        A client to use instead of connecting to ``scheduler``.

    Dask runs chunks in parallel, so each task decodes and computes on one thread
    (:attr:`inner_threads`): points per second then grow with the worker count
    instead of the tasks competing for the same cores.
    """

    #: Threads of one task's decoding and kernels.
    inner_threads = 1

    def __init__(self, scheduler: str = "threads", *, workers: int | None = None,
                 client: Any = None) -> None:
        self.scheduler = scheduler
        self.workers = workers
        self._client = client
        self._own_client = False
        self._pool: Any = None
        if client is None and scheduler not in ("threads", "processes"):
            if "://" not in scheduler:
                raise InputError(f"--scheduler expects threads, processes or tcp://HOST:PORT, "
                                 f"got {scheduler!r}")
            _import_dask()
            try:
                from distributed import Client
            except ImportError:
                raise InputError("a distributed scheduler needs dask.distributed: "
                                 "pip install 'rough_viewer[dask]'") from None
            probe_scheduler(scheduler)
            try:
                self._client = Client(scheduler, timeout="10s")
            except OSError as exc:
                raise InputError(f"cannot reach the Dask scheduler at {scheduler}: "
                                 f"{error_line(exc)}") from None
            except Exception as exc:  # e.g. a server that answers, but not in Dask's protocol
                raise InputError(f"{scheduler} did not answer as a Dask scheduler: "
                                 f"{error_line(exc)}") from None
            self._own_client = True

    @property
    def dashboard_link(self) -> str | None:
        """The distributed scheduler's dashboard URL (None for local schedulers)."""
        if self._client is None:
            return None
        return str(self._client.dashboard_link)

    @property
    def parallel(self) -> int:
        """Chunks that may be in memory at once in one process (sizes the chunks)."""
        if self._client is not None:
            nthreads = self._client.nthreads()
            return max(nthreads.values()) if nthreads else 1
        if self.scheduler == "threads":
            import os

            return int(self.workers or os.cpu_count() or 1)
        return 1

    def close(self) -> None:
        """Close the client or the process pool this runner opened."""
        if self._own_client and self._client is not None:
            self._client.close()
            self._client = None
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def _process_pool(self) -> Any:
        """One pool of worker processes for every pass of this runner (Dask's
        ``processes`` scheduler would start a new pool for every pass)."""
        if self._pool is None:
            import multiprocessing
            import os
            from concurrent.futures import ProcessPoolExecutor

            self._pool = ProcessPoolExecutor(
                max_workers=int(self.workers or os.cpu_count() or 1),
                mp_context=multiprocessing.get_context("spawn"), initializer=_one_thread)
        return self._pool

    def __enter__(self) -> DaskRunner:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def map_reduce(self, sources: Sequence[Source], chunk_points: int, task: ChunkTask,
                   n_out: int, on_chunk: ChunkDone, check: Callable[[int], None]
                   ) -> list[Partial]:
        dask = _import_dask()
        from dask import delayed

        run = next(_RUN)
        chunks = chunk_plan(sources, chunk_points)
        task_d = delayed(task, pure=True)
        maps = [delayed(_map_chunk, pure=True)(sources[c.source], c, task_d,
                                                dask_key_name=f"rv-map-{run}-{i}")
                for i, c in enumerate(chunks)]
        # one tree for all outputs: each merge task adds the lists of two subtrees
        # output by output (no task per output and chunk just to pick its table)
        level, depth = list(maps), 0
        while len(level) > 1:
            level = [delayed(_merge_lists, pure=True)(
                         level[i], level[i + 1], dask_key_name=f"rv-merge-{run}-{depth}-{i}")
                     if i + 1 < len(level) else level[i]
                     for i in range(0, len(level), 2)]
            depth += 1
        finals = [delayed(_pick, pure=True)(level[0], g, dask_key_name=f"rv-pick-{run}-{g}")
                  for g in range(n_out)]
        if self._client is not None:
            return self._run_distributed(maps, finals, chunks, on_chunk)
        from dask.callbacks import Callback

        prefix = f"rv-map-{run}-"

        class _Progress(Callback):
            def _posttask(self, key, result, dsk, state, id):  # noqa: A002
                if isinstance(key, str) and key.startswith(prefix):
                    on_chunk(chunks[int(key[len(prefix):])])

        kwargs: dict[str, Any] = {"scheduler": self.scheduler}
        if self.scheduler == "processes":
            kwargs["pool"] = self._process_pool()
        elif self.workers:
            kwargs["num_workers"] = int(self.workers)
        with _Progress():
            out = dask.compute(*finals, **kwargs)
        return list(out)

    def run_tiles(self, copc: Any, source: Source, plan: Any, ctx: Any, tops: list,
                  on_points: Callable[[int], None]) -> Iterator[tuple[int, Any]]:
        """The tiles of a COPC file as tasks (:mod:`rough_viewer.scale.tiles`), one per
        tile: each reads and decodes its own nodes and gives back its cells' rows and
        its seam points; yielded as they finish."""
        from dataclasses import replace

        from rough_viewer.scale.tiles import tile_task

        ctx = replace(ctx, threads=self.inner_threads)
        jobs = [(source.path, source, plan.tiles[t], t, tops[t]) for t in range(plan.n_tiles)]
        if self._client is not None:
            from distributed import as_completed

            client = self._client
            ctx_f = client.scatter(ctx, broadcast=True)
            futures = [client.submit(tile_task, *job[:4], ctx_f, job[4], False, pure=False,
                                     key=f"rv-tile-{next(_RUN)}-{job[3]}") for job in jobs]
            number = {f.key: job[3] for f, job in zip(futures, jobs, strict=True)}
            try:
                for f in as_completed(futures):
                    out = f.result()
                    on_points(out.n_points)
                    yield number[f.key], out
            except BaseException:
                client.cancel(futures)
                raise
            return
        from concurrent.futures import ThreadPoolExecutor
        from concurrent.futures import as_completed as done_first
        from concurrent.futures.process import BrokenProcessPool

        threads = self.scheduler == "threads"
        pool = ThreadPoolExecutor(max_workers=int(self.workers or os.cpu_count() or 1)) \
            if threads else self._process_pool()
        try:
            pending = {pool.submit(tile_task, *job[:4], ctx, job[4], threads): job[3]
                       for job in jobs}
            try:
                for f in done_first(pending):
                    out = f.result()
                    on_points(out.n_points)
                    yield pending[f], out
            except BrokenProcessPool:
                raise InputError(f"a worker process died reading {source.path} (its memory "
                                 "or a crash in the LAZ decoder); the file may be damaged") from None
            finally:
                for f in pending:
                    f.cancel()
        finally:
            if threads:
                pool.shutdown(wait=True, cancel_futures=True)

    def _run_distributed(self, maps: list, finals: list, chunks: list[Chunk],
                         on_chunk: ChunkDone) -> list[Partial]:
        from distributed import as_completed

        client = self._client
        futures = client.compute([*maps, *finals])
        map_futures = futures[:len(maps)]
        index = {f.key: i for i, f in enumerate(map_futures)}
        try:
            for f in as_completed(map_futures):
                if f.status == "error":
                    f.result()  # raises the task's error here
                on_chunk(chunks[index[f.key]])
            return list(client.gather(futures[len(maps):]))
        except BaseException:
            client.cancel(futures)
            raise
