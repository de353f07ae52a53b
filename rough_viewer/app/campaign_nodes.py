"""The nodes of a campaign's COPC file, for the browser tabs: level of detail straight
from the file's hierarchy (docs/campaign.md "Serving a campaign").

A campaign's tabs choose their nodes from :class:`~rough_viewer.lod.copc.CopcTree`
(the file's hierarchy, no point read) with the one selection of
:func:`rough_viewer.lod.select.select_nodes`, each tab within its point budget.
:class:`CopcNodes` gives the scene a node's points:

- a node of the **overview** (the top levels the app's cloud holds) is rows of the
  app's cloud (:meth:`CopcNodes.rows`): never decoded again;
- a deeper node is decoded **on demand** in the reader sandbox
  (:func:`rough_viewer.scale.tiles.decoded_tiles`: a node that crashes its decoder
  is one line) by a thread of its own, never the app's worker: a tab's refinement
  asks for the nodes it lacks (:meth:`CopcNodes.want`: a newer view of the same tab
  replaces its older wishes) and shows what it has; the thread decodes the nodes
  wished for, largest on the screen first, one request to the reader child per batch
  of at most :data:`BATCH_POINTS` points (the child decodes the next node while this
  process stores the last), and calls back (:meth:`CopcNodes.listen`) with the tabs
  whose nodes came, at most every :data:`READY_EVERY_S`, so that they refine again;
- decoded nodes are kept in :class:`NodeCache`, a least-recently-used cache bounded
  in bytes (:data:`NODE_CACHE_BYTES`; x, y, z float64, :data:`BYTES_PER_POINT` a
  point, known from the hierarchy's count before decoding): a node that could not fit
  it alone is not decoded (one line), and the scene asks again for a node it needs
  that was evicted (its colours after a recolour).

Memory: the cache's bound, the node tree (:data:`rough_viewer.lod.copc.NODE_BYTES`
a node) and one node in flight; nothing grows with the file's points.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from rough_viewer.io.copc.reader import CopcFile
from rough_viewer.lod.copc import CopcTree, copc_tree
from rough_viewer.memory import format_bytes
from rough_viewer.scale.sources import Source
from rough_viewer.vocabulary import InputError

#: Bytes the decoded nodes may hold, by default (5.6 M points: a tab's default budget
#: of 3 M with room to spare).
NODE_CACHE_BYTES = 128 << 20
#: Bytes a decoded point holds in the cache (x, y, z float64, metres).
BYTES_PER_POINT = 24
#: Most points one request to the reader child decodes (a batch); the next batch
#: takes the wishes as they are then.
BATCH_POINTS = 1_000_000
#: Least seconds between two calls of the ready callback while a batch decodes.
READY_EVERY_S = 0.25


@dataclass(frozen=True)
class DecodedNode:
    """A node's points, metres, the cloud's frame (the file's coordinates)."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray

    @property
    def n(self) -> int:
        return int(self.x.shape[0])

    @property
    def nbytes(self) -> int:
        return int(self.x.nbytes + self.y.nbytes + self.z.nbytes)


class NodeCache:
    """Decoded nodes, least recently used first out, at most ``max_bytes`` (the bytes
    of a node: :attr:`DecodedNode.nbytes`). Thread-safe.

    >>> c = NodeCache(100)
    >>> pts = lambda n: DecodedNode(np.zeros(n), np.zeros(n), np.zeros(n))
    >>> c.put(1, pts(2)), c.put(2, pts(2)), c.get(1) is not None, c.put(3, pts(2))
    (True, True, True, True)
    >>> sorted(c.keys()), c.nbytes, c.put(4, pts(5))   # 2 went (least recently used)
    ([1, 3], 96, False)
    """

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = int(max_bytes)
        self._nodes: OrderedDict[int, DecodedNode] = OrderedDict()
        self._lock = threading.Lock()
        self.nbytes = 0
        self.peak_bytes = 0
        """The most bytes held at once."""
        self.evicted = 0
        """Nodes dropped to make room."""

    def fits(self, nbytes: int) -> bool:
        """Whether a node of ``nbytes`` could be held at all."""
        return int(nbytes) <= self.max_bytes

    def get(self, k: int) -> DecodedNode | None:
        with self._lock:
            node = self._nodes.get(k)
            if node is not None:
                self._nodes.move_to_end(k)
            return node

    def __contains__(self, k: object) -> bool:
        with self._lock:
            return k in self._nodes

    def keys(self) -> list[int]:
        with self._lock:
            return list(self._nodes)

    def put(self, k: int, node: DecodedNode) -> bool:
        """Hold ``node`` (dropping the least recently used to make room); False, and
        nothing held, when it alone is larger than the bound."""
        size = node.nbytes
        if not self.fits(size):
            return False
        with self._lock:
            old = self._nodes.pop(k, None)
            if old is not None:
                self.nbytes -= old.nbytes
            while self._nodes and self.nbytes + size > self.max_bytes:
                _, gone = self._nodes.popitem(last=False)
                self.nbytes -= gone.nbytes
                self.evicted += 1
            self._nodes[k] = node
            self.nbytes += size
            self.peak_bytes = max(self.peak_bytes, self.nbytes)
        return True

    def clear(self) -> None:
        with self._lock:
            self._nodes.clear()
            self.nbytes = 0


def overview_starts(copc: CopcFile, tree: CopcTree, n_overview: int) -> np.ndarray:
    """(M,) int64 first row, in the overview (the app's cloud), of each tree node's
    points, -1 for a node the overview does not hold: the overview is the file's
    nodes of the shallowest levels whose points add up to ``n_overview``, decoded in
    the file's node order (:func:`rough_viewer.app.campaign.read_overview`). All -1
    when no whole levels add up to it."""
    depth = copc.nodes["depth"].astype(np.int64)
    counts = copc.nodes["count"].astype(np.int64)
    out = np.full(tree.n_nodes, -1, dtype=np.int64)
    levels = np.unique(depth)
    total = np.cumsum([int(counts[depth == d].sum()) for d in levels])
    hit = np.flatnonzero(total == int(n_overview))
    if hit.size == 0:
        return out
    rows = np.flatnonzero(depth <= levels[int(hit[0])])
    starts = np.concatenate(([0], np.cumsum(counts[rows])[:-1]))
    where = np.full(copc.nodes.shape[0], -1, dtype=np.int64)
    where[rows] = starts
    real = tree.file_row >= 0
    out[real] = where[tree.file_row[real]]
    return out


Ready = Callable[[frozenset[int]], None]
Failed = Callable[[str], None]


class CopcNodes:
    """The points of a campaign's tree nodes for the scene (see the module's text).

    Parameters
    ----------
    copc, source
        The campaign's file (:class:`rough_viewer.app.campaign.Campaign`).
    tree
        Its :func:`~rough_viewer.lod.copc.copc_tree`.
    starts
        :func:`overview_starts`: where the overview holds each node.
    cache_bytes
        The bound of the decoded nodes' cache.
    """

    def __init__(self, copc: CopcFile, source: Source, tree: CopcTree, starts: np.ndarray, *,
                 cache_bytes: int = NODE_CACHE_BYTES, batch_points: int = BATCH_POINTS) -> None:
        self.copc, self.source, self.tree = copc, source, tree
        self._starts = starts
        self.cache = NodeCache(cache_bytes)
        self.batch_points = int(batch_points)
        self._cond = threading.Condition()
        self._wants: dict[int, list[int]] = {}
        self._failed: dict[int, str] = {}
        self._ready: Ready | None = None
        self._said: Failed | None = None
        self._thread: threading.Thread | None = None
        self._closed = False
        self._busy = False
        self.decoded_nodes = 0
        """Nodes decoded so far (each decode counted; a node evicted and wanted again
        is decoded again)."""
        self.decoded_points = 0
        self.requests = 0
        """Requests to the reader child (batches)."""

    # ------------------------------------------------------------------ the scene's
    def listen(self, ready: Ready | None, failed: Failed | None) -> None:
        """``ready(client_ids)`` when nodes those tabs wished for came (the decoding
        thread calls it: submit a job); ``failed(line)`` for a node that could not be
        decoded or held."""
        with self._cond:
            self._ready, self._said = ready, failed

    def in_overview(self, k: int) -> bool:
        return bool(self._starts[k] >= 0) or int(self.tree.node_counts[k]) == 0

    def rows(self, k: int) -> np.ndarray | None:
        """Rows of node ``k``'s points in the app's cloud (an empty node: none), or
        None for a node the overview does not hold."""
        s = int(self._starts[k])
        c = int(self.tree.node_counts[k])
        if c == 0:
            return np.empty(0, dtype=np.int64)
        if s < 0:
            return None
        return np.arange(s, s + c, dtype=np.int64)

    def points(self, k: int) -> DecodedNode | None:
        """Node ``k``'s decoded points, if the cache holds them."""
        return self.cache.get(int(k))

    def has(self, k: int) -> bool:
        """Whether node ``k``'s points are at hand (overview, empty, or cached)."""
        return self.in_overview(k) or int(k) in self.cache

    def failed(self, k: int) -> bool:
        """Whether node ``k`` could not be decoded or held (never asked for again)."""
        with self._cond:
            return int(k) in self._failed

    def want(self, client_id: int, nodes: Sequence[int]) -> None:
        """Tab ``client_id`` wishes for ``nodes`` (largest on its screen first),
        replacing what it wished for before; those not at hand are decoded."""
        todo = [int(k) for k in nodes if not self.has(int(k))]
        with self._cond:
            if self._closed:
                return
            if todo:
                self._wants[client_id] = todo
            else:
                self._wants.pop(client_id, None)
            if todo and self._thread is None:
                self._thread = threading.Thread(target=self._run, daemon=True,
                                                name="rough-viewer-copc-nodes")
                self._thread.start()
            self._cond.notify_all()

    def forget(self, client_id: int) -> None:
        """A tab left: its wishes go."""
        with self._cond:
            self._wants.pop(client_id, None)

    @property
    def idle(self) -> bool:
        """Nothing wished for is left to decode, and no batch is in flight."""
        with self._cond:
            return not self._busy and not self._todo()

    def close(self) -> None:
        """Stop the decoding thread (after the node in flight) and drop the cache."""
        with self._cond:
            self._closed = True
            self._wants.clear()
            self._cond.notify_all()
        self.cache.clear()

    # ------------------------------------------------------------------ the thread
    def _todo(self) -> list[int]:
        """Nodes wished for, each tab's in its order, the tabs in turn (under the
        lock). A node decoded leaves every wish (:meth:`_served`): one wish decodes a
        node once, even where the cache cannot hold all it asked for."""
        lists = list(self._wants.values())
        out: list[int] = []
        seen: set[int] = set()
        for i in range(max((len(v) for v in lists), default=0)):
            for v in lists:
                if i < len(v):
                    k = v[i]
                    if k not in seen and k not in self._failed:
                        seen.add(k)
                        out.append(k)
        return out

    def _served(self, k: int) -> None:
        """Node ``k`` was decoded (or failed): out of every wish (under the lock)."""
        for client in list(self._wants):
            rest = [j for j in self._wants[client] if j != k]
            if rest:
                self._wants[client] = rest
            else:
                del self._wants[client]

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._closed and not self._todo():
                    self._busy = False
                    self._cond.wait()
                if self._closed:
                    self._busy = False
                    return
                self._busy = True
                batch = self._batch(self._todo())
            try:
                self._decode(batch)
            except Exception as exc:  # noqa: BLE001 - never take the server down
                self._fail(batch[0], f"{self.copc.path}: the nodes could not be decoded "
                           f"({type(exc).__name__}: {exc})")

    def _batch(self, todo: list[int]) -> list[int]:
        """The first nodes of ``todo`` up to :attr:`batch_points` (at least one), the
        ones too large for the cache refused (under the lock)."""
        out: list[int] = []
        points = 0
        for k in todo:
            c = int(self.tree.node_counts[k])
            if not self.cache.fits(c * BYTES_PER_POINT):
                self._failed[k] = self._too_big(k, c)
                self._tell(self._failed[k])
                continue
            if out and points + c > self.batch_points:
                break
            out.append(k)
            points += c
        return out

    def _name(self, k: int) -> str:
        e = self.copc.nodes[int(self.tree.file_row[k])]
        return f"{int(e['depth'])}-{int(e['x'])}-{int(e['y'])}-{int(e['z'])}"

    def _too_big(self, k: int, count: int) -> str:
        return (f"{self.copc.path}: node {self._name(k)} holds {count:,} points "
                f"({format_bytes(count * BYTES_PER_POINT)} decoded), more than the "
                f"{format_bytes(self.cache.max_bytes)} the decoded nodes may hold: not drawn")

    def _decode(self, batch: list[int]) -> None:
        from rough_viewer.scale.tiles import decoded_tiles

        if not batch:
            return
        self.requests += 1
        groups = [np.array([int(self.tree.file_row[k])], dtype=np.int64) for k in batch]
        items = decoded_tiles(self.copc, self.source, groups)
        arrived: set[int] = set()
        last = time.monotonic()
        got = 0  # items received: the node in flight is batch[got]
        try:
            for x, y, z in items:
                k = batch[got]
                got += 1
                if x.shape[0] != int(self.tree.node_counts[k]):
                    self._fail(k, f"{self.copc.path}: node {self._name(k)} decodes to "
                               f"{x.shape[0]:,} points where its hierarchy says "
                               f"{int(self.tree.node_counts[k]):,}; the file is damaged")
                    continue
                self.cache.put(k, DecodedNode(x, y, z))
                self.decoded_nodes += 1
                self.decoded_points += int(x.shape[0])
                arrived.add(k)
                now = time.monotonic()
                if now - last >= READY_EVERY_S:
                    self._arrived(arrived)
                    arrived, last = set(), now
                if not self._still_wanted(batch[got:]):
                    break  # the tabs look elsewhere now: the next batch is theirs
        except InputError as exc:
            self._fail(batch[min(got, len(batch) - 1)], str(exc))
        finally:
            close = getattr(items, "close", None)
            if close is not None:
                close()  # stops the reader child of a batch left early
            self._arrived(arrived)

    def _still_wanted(self, rest: list[int]) -> bool:
        if not rest:
            return True
        with self._cond:
            if self._closed:
                return False
            wanted = {k for v in self._wants.values() for k in v}
        return any(k in wanted for k in rest)

    def _arrived(self, nodes: set[int]) -> None:
        if not nodes:
            return
        with self._cond:
            clients = frozenset(c for c, v in self._wants.items() if nodes.intersection(v))
            for k in nodes:
                self._served(k)
            ready = self._ready
        if clients and ready is not None:
            ready(clients)

    def _fail(self, k: int, message: str) -> None:
        with self._cond:
            self._failed[k] = message
            self._served(k)
        self._tell(message)

    def _tell(self, message: str) -> None:
        said = self._said
        if said is not None:
            said(message)


def campaign_nodes(copc: CopcFile, source: Source, n_overview: int, *,
                   cache_bytes: int = NODE_CACHE_BYTES) -> CopcNodes:
    """The tree of ``copc``'s hierarchy in metres and its nodes' points, the overview's
    ``n_overview`` points (the app's cloud) serving its top levels."""
    tree = copc_tree(copc, factor=source.factor, z_factor=source.z_factor)
    return CopcNodes(copc, source, tree, overview_starts(copc, tree, n_overview),
                     cache_bytes=cache_bytes)


__all__ = ["BYTES_PER_POINT", "NODE_CACHE_BYTES", "CopcNodes", "DecodedNode", "NodeCache",
           "campaign_nodes", "overview_starts"]
