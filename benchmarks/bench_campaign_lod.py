"""Level of detail straight from a campaign's COPC nodes (issue 33 item 3's target: a
patch 1.5 m in front of the camera complete, >= 95 % of its points, within the
budget, the server's tree of processes under 2 GB).

    flock /tmp/rough_viewer_heavy.lock python benchmarks/bench_campaign_lod.py \\
        [--copc /work/bench/p20m/campaign.copc.laz] [--memory 2GB] [--budget 3000000] \\
        [--repeat 3]

Each run starts ``rough-viewer serve CAMPAIGN --memory 2GB --point-budget B`` as a
process (the first run on an empty cells cache: the map's pass over every point; the
next ones read the cells from the disk), opens a websocket tab (the test suite's
protocol client, a 1920 x 1080 window, 50 degrees) whose camera looks at the whole
face from 60 m, waits for its first nodes and 3 s more, then moves its camera 1.5 m in front of three patches of the synthetic outcrop's face (100
m x 20 m facing -y, ``bench_lod.py``) in turn. A patch is the points of the file
within 10 cm of the spot along the face (x and z); they are known by node (this
process decodes the few nodes whose cubes meet the patch, from the file), and the tab
holds a point when the node holding it is among those it was sent and shows (its
``/lod/K`` messages: K is the tree's row). Printed, per run and as medians: seconds
from the URL to the first nodes; per patch, seconds from the camera message until
95 % and until all of the patch is shown, the share shown then, the points the tab
shows against its budget; the peak resident memory of the server's process tree
(the server and its reader children, sampled every 50 ms) and the server's own peak
(``VmHWM``).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

#: Spots of the face the camera looks at: shares of the file's extent along the two
#: long axes of its bounding box (the face; the thin axis is the one it faces).
SPOTS = ((0.5, 0.5), (0.23, 0.3), (0.78, 0.7))
#: Half the patch's side along the face, metres.
HALF = 0.1
#: How far the tab's first camera stands from the face (the whole face in view), m.
FAR_M = 60.0


def tree_rss(pid: int) -> int:
    """Resident bytes of process ``pid`` and its descendants now."""
    kids: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as fh:
                    ppid = int(fh.read().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            kids.setdefault(ppid, []).append(int(entry))
    total, todo = 0, [pid]
    while todo:
        p = todo.pop()
        todo.extend(kids.get(p, []))
        try:
            with open(f"/proc/{p}/status") as fh:
                for line in fh:
                    if line.startswith("VmRSS:"):
                        total += int(line.split()[1]) * 1024
        except OSError:
            pass
    return total


class Sampler:
    """The largest :func:`tree_rss` of a process, sampled on a thread."""

    def __init__(self, pid: int, every: float = 0.05) -> None:
        self.pid, self.every, self.peak, self._stop = pid, every, 0, False
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop:
            self.peak = max(self.peak, tree_rss(self.pid))
            time.sleep(self.every)

    def stop(self) -> int:
        self._stop = True
        self._thread.join(5)
        return self.peak


def patch_nodes(path: str, spot: tuple[float, float]
                ) -> tuple[dict[int, int], np.ndarray, np.ndarray]:
    """The patch at ``spot``: {tree row: points of the patch in that node}, the spot's
    point on the face (the patch's median across it), metres, and the unit vector
    the face looks along (the bounding box's thin axis, towards its low side)."""
    from rough_viewer.io.copc.reader import decode_nodes, open_copc
    from rough_viewer.lod.copc import copc_tree

    copc = open_copc(path)
    tree = copc_tree(copc)
    thin = int(np.argmin(copc.maxs - copc.mins))
    a, b = (ax for ax in range(3) if ax != thin)
    target = copc.mins + 0.5 * (copc.maxs - copc.mins)
    target[a] = copc.mins[a] + spot[0] * (copc.maxs[a] - copc.mins[a])
    target[b] = copc.mins[b] + spot[1] * (copc.maxs[b] - copc.mins[b])
    lo, hi = tree.cube_lo, tree.cube_lo + tree.cube_size
    meets = np.flatnonzero((lo[:, a] <= target[a] + HALF) & (hi[:, a] >= target[a] - HALF)
                           & (lo[:, b] <= target[b] + HALF) & (hi[:, b] >= target[b] - HALF)
                           & (tree.file_row >= 0))
    out: dict[int, int] = {}
    across = []
    for k in meets:
        cols = decode_nodes(copc, [int(tree.file_row[k])])
        inside = (np.abs(cols[a] - target[a]) < HALF) & (np.abs(cols[b] - target[b]) < HALF)
        if inside.any():
            out[int(k)] = int(inside.sum())
            across.append(cols[thin][inside])
    target[thin] = float(np.median(np.concatenate(across)))
    normal = np.zeros(3)
    normal[thin] = -1.0
    return out, target, normal


def shown_nodes(client) -> tuple[set[int], int]:
    """The /lod/ nodes a tab shows now (from its messages), and their points."""
    sizes: dict[int, int] = {}
    visible: dict[int, bool] = {}
    for m in list(client.messages):
        name = m.get("name", "")
        if not name.startswith("/lod/"):
            continue
        k = int(name.rsplit("/", 1)[1])
        kind = m.get("type")
        if kind == "PointCloudMessage":
            sizes[k] = int(np.asarray(m["props"]["points"]).size // 3)
            visible[k] = True
        elif kind == "SetSceneNodeVisibilityMessage":
            visible[k] = bool(m["visible"])
        elif kind == "RemoveSceneNodeMessage":
            sizes.pop(k, None)
    shown = {k for k in sizes if visible.get(k)}
    return shown, sum(sizes[k] for k in shown)


def one_run(path: str, memory: str, budget: int, patches, cache: str) -> dict[str, float]:
    from tests.app.protocol import ProtocolClient
    from tests.app.serve_process import ServeProcess

    os.environ["ROUGH_VIEWER_CACHE"] = cache
    t0 = time.perf_counter()
    proc = ServeProcess(path, "--memory", memory, "--no-token", "--point-budget", str(budget),
                        timeout=600)
    sampler = Sampler(proc.proc.pid)
    out: dict[str, float] = {}
    try:
        t_url = time.perf_counter()
        client = ProtocolClient(proc.port, proc.path)
        # the overview's root sets the display frame: its centre rounded to metres
        from rough_viewer.app.campaign import open_campaign, overview_cap, read_overview

        origin = _origin(path, memory, open_campaign, overview_cap, read_overview)
        _, centre, normal = patches[0]
        far = np.array(centre) + FAR_M * np.asarray(normal)
        client.look_from(far - origin, centre - origin, fov=0.87, width=1920, height=1080)
        while not shown_nodes(client)[0]:
            time.sleep(0.02)
        out["first_nodes_s"] = time.perf_counter() - t_url
        out["url_s"] = t_url - t0
        time.sleep(3.0)  # the whole face from afar first: no patch's deep nodes yet

        for i, (nodes, spot, normal) in enumerate(patches):
            origin = _origin(path, memory, open_campaign, overview_cap, read_overview)
            total = sum(nodes.values())
            eye = spot + 1.5 * normal
            t1 = time.perf_counter()
            client.look_from(eye - origin, spot - origin, fov=0.87, width=1920, height=1080)
            t95 = None
            share = 0.0
            while time.perf_counter() - t1 < 120:
                shown, points = shown_nodes(client)
                share = sum(c for k, c in nodes.items() if k in shown) / total
                if t95 is None and share >= 0.95:
                    t95 = time.perf_counter() - t1
                if share >= 1.0:
                    break
                time.sleep(0.02)
            done = time.perf_counter() - t1
            time.sleep(1.0)  # what the tab shows once it settled
            shown, points = shown_nodes(client)
            out[f"p{i}_95_s"] = t95 if t95 is not None else float("nan")
            out[f"p{i}_all_s"] = done if share >= 1.0 else float("nan")
            out[f"p{i}_share"] = sum(c for k, c in nodes.items() if k in shown) / total
            out[f"p{i}_shown"] = points
            out[f"p{i}_points"] = total
        client.close()
        out["server_hwm"] = proc.memory()["VmHWM"]
    finally:
        out["tree_peak"] = sampler.stop()
        proc.stop()
    return out


_ORIGIN: dict[str, np.ndarray] = {}


def _origin(path, memory, open_campaign, overview_cap, read_overview) -> np.ndarray:
    """The app's display frame: the overview's bounding-box centre rounded to metres."""
    if path not in _ORIGIN:
        from rough_viewer.scale.chunked import parse_bytes

        cap = overview_cap(float(parse_bytes(memory)))
        ov = read_overview(open_campaign(path), cap)
        lo, hi = ov.bounds()
        _ORIGIN[path] = np.round(0.5 * (lo + hi))
    return _ORIGIN[path]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--copc", default="/work/bench/p20m/campaign.copc.laz")
    ap.add_argument("--memory", default="2GB")
    ap.add_argument("--budget", type=int, default=3_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    patches = [patch_nodes(args.copc, s) for s in SPOTS]
    load = os.getloadavg()
    runs = []
    with tempfile.TemporaryDirectory(prefix="rv-bench-campaign-lod-") as cache:
        for r in range(args.repeat + 1):  # the first on an empty cells cache
            runs.append(one_run(args.copc, args.memory, args.budget, patches, cache))
            got = runs[-1]
            print(f"run {r} ({'cold: the map pass' if r == 0 else 'cells from disk'}): "
                  f"first nodes {got['first_nodes_s']:.2f} s after the URL; "
                  + "; ".join(f"patch {i}: 95 % {got[f'p{i}_95_s']:.2f} s, all "
                              f"{got[f'p{i}_all_s']:.2f} s, {got[f'p{i}_share']:.1%} of "
                              f"{int(got[f'p{i}_points'])} shown, tab {int(got[f'p{i}_shown']):,}"
                              for i in range(len(SPOTS)))
                  + f"; peak tree {got['tree_peak'] / 2**20:,.0f} MiB, server "
                  f"{got['server_hwm'] / 2**20:,.0f} MiB", flush=True)
    warm = runs[1:] or runs

    def med(key: str, rs=warm) -> float:
        return statistics.median(r[key] for r in rs)

    n_patch = len(SPOTS)
    print(f"{args.copc}: --memory {args.memory}, budget {args.budget:,}; medians of "
          f"{len(warm)} runs with the cells on disk (run 0: cold); load before "
          f"{' '.join(f'{v:.2f}' for v in load)}, after "
          f"{' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    print(f"  first nodes after the URL          {med('first_nodes_s'):6.2f} s "
          f"(cold {runs[0]['first_nodes_s']:.2f} s)")
    for i in range(n_patch):
        print(f"  patch {i} ({int(med(f'p{i}_points'))} points): 95 % in "
              f"{med(f'p{i}_95_s'):.2f} s, all in {med(f'p{i}_all_s'):.2f} s, "
              f"{med(f'p{i}_share'):.1%} shown, tab {int(med(f'p{i}_shown')):,} points "
              f"of {args.budget:,} (cold run: 95 % in {runs[0][f'p{i}_95_s']:.2f} s)")
    print(f"  peak RSS of the server's tree       {med('tree_peak') / 2**20:6.0f} MiB "
          f"(cold {runs[0]['tree_peak'] / 2**20:.0f} MiB); the server alone "
          f"{med('server_hwm') / 2**20:.0f} MiB (cold {runs[0]['server_hwm'] / 2**20:.0f} MiB)")


if __name__ == "__main__":
    main()
