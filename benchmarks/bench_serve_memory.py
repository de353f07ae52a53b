"""What the ``serve`` app holds per point once a cloud is prepared: the figure of
``rough_viewer.app.limits.APP_BYTES_PER_POINT`` that ``serve --memory`` checks
before reading (issue 33 item 4).

    PYTHONPATH=. python benchmarks/bench_serve_memory.py [--points 500000 2000000] [--repeat 1]

For each size a synthetic face is written as a LAZ file, then a fresh process does
what ``serve`` does without a browser: reads it (``load_inputs``: the LAZ decoded in
the isolated child), builds the app (``build_app`` with serve's defaults: panels and
idle prefetch of the preset grids on) and waits until it is idle (first map, panels,
presets cached). The process reports its resident memory (``VmRSS``) and its peak
(``VmHWM``) once idle, and while reading its own peak plus the isolated reader's
(``RUSAGE_CHILDREN``); beside them, the need ``serve --memory`` counts for the file
(:func:`rough_viewer.app.files.serve_need`, from its header). The figure is the slope between the two
largest sizes (the interpreter, viser and the libraries, the same for every size,
drop out), of the resident memory once idle ("held") and of the peak ("peak");
prints the median over ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

_CHILD = r"""
import json, sys
from pathlib import Path
def status():
    out = {}
    for line in open("/proc/self/status"):
        k, _, v = line.partition(":")
        if k in ("VmRSS", "VmHWM"):
            out[k] = int(v.split()[0]) * 1024
    return out
import viser
from rough_viewer.app.cloud import grid_presets
from rough_viewer.app.server import build_app
from rough_viewer.cli._inputs import load_inputs
before = status()
cloud = load_inputs([Path(sys.argv[1])], quiet=True, max_points=10**9)
import resource
read = {"parent": status()["VmHWM"],
        "reader": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024}
n = cloud.n
server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
app = build_app(server, cloud, presets=grid_presets(cloud), data_dir=Path(sys.argv[1]).parent,
                prefetch=sys.argv[2] == "1")
del cloud
app.wait_idle(None)
after = status()
app.stop(); server.stop()
print(json.dumps({"n": n, "before": before, "after": after, "read": read}))
"""


def measure(path: Path, prefetch: bool) -> dict:
    out = subprocess.run([sys.executable, "-c", _CHILD, str(path), "1" if prefetch else "0"],
                         capture_output=True, text=True)
    if out.returncode:
        raise SystemExit(f"the measuring process failed:\n{out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--points", type=int, nargs="+", default=[500_000, 2_000_000])
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--no-prefetch", action="store_true",
                        help="idle prefetch of the presets off (serve has it on)")
    args = parser.parse_args()
    from benchmarks.bench_app import synthetic_face
    from rough_viewer.app.files import serve_need
    from rough_viewer.app.limits import APP_BYTES_PER_POINT
    from rough_viewer.io.formats.las import write_las

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in sorted(args.points):
            path = Path(tmp) / f"face{n}.laz"
            write_las(path, synthetic_face(n))
            runs = [measure(path, not args.no_prefetch) for _ in range(args.repeat)]
            held = statistics.median(r["after"]["VmRSS"] for r in runs)
            peak = statistics.median(r["after"]["VmHWM"] for r in runs)
            reading = statistics.median(r["read"]["parent"] + r["read"]["reader"] for r in runs)
            rows.append((n, held, peak))
            need = serve_need([path]).total
            print(f"{n:>11,} points: held once idle {held / 2**20:8.0f} MiB, "
                  f"peak {peak / 2**20:8.0f} MiB, while reading (server + reader) "
                  f"{reading / 2**20:8.0f} MiB; serve --memory counts "
                  f"{need / 2**20:8.0f} MiB", flush=True)
    if len(rows) >= 2:
        (n0, h0, p0), (n1, h1, p1) = rows[-2], rows[-1]
        print(f"per point: held {(h1 - h0) / (n1 - n0):.0f} B, peak {(p1 - p0) / (n1 - n0):.0f} B "
              f"(APP_BYTES_PER_POINT = {APP_BYTES_PER_POINT:g})")


if __name__ == "__main__":
    main()
