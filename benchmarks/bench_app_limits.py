"""What hostile or careless browsers cost a ``rough-viewer serve`` process, and what
the grid cache holds.

    PYTHONPATH=. python benchmarks/bench_app_limits.py [--repeat 3] [--cache]

For each case a fresh ``serve`` process (20,000 points, ``--max-upload-mb 16``) is
started, a protocol-level client (tests/app/protocol.py) does the case, and the
process's peak resident memory (``VmHWM``) before and after is printed (medians of
``--repeat`` runs):

- a 200 MiB upload (refused at its start: above the limit);
- a 64 MiB upload that announced 1 MiB (cut off);
- a 20,000-point LAZ whose header declares 50,000,000 points (uploaded, and through
  "Load file");
- an accepted 13 MiB text upload of 400,000 points (streamed to disk, then parsed).

``--cache`` also prints the bytes the grid cache holds on the demo outcrop per
grid size (the budget is ``rough_viewer.app.limits.CACHE_BYTES``).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

MiB = 1 << 20


def _case(folder: Path, name: str) -> tuple[float, float]:
    from tests.app.protocol import ProtocolClient
    from tests.app.serve_process import ServeProcess

    proc = ServeProcess(str(folder / "face.npy"), "--max-upload-mb", "16", "--no-token")
    client = ProtocolClient(proc.port, "/")
    try:
        client.uuid("Upload file")
        time.sleep(1.0)
        before = proc.memory()["VmHWM"] / MiB
        if name == "refused 200 MiB upload":
            client.upload("Upload file", "huge.xyz", b"0.0 0.0 0.0\n" * (200 * MiB // 12))
            _notice(client, "more than the upload limit")
        elif name == "64 MiB upload announced as 1 MiB":
            client.upload("Upload file", "liar.xyz", b"1.0 2.0 3.0\n" * (64 * MiB // 12),
                          declared=MiB)
            _notice(client, "larger than announced")
        elif name == "LAZ bomb, uploaded":
            client.upload("Upload file", "bomb.laz", (folder / "bomb.laz").read_bytes())
            _notice(client, "50,000,000")
        elif name == "LAZ bomb, Load file":
            client.set_value("File path", "bomb.laz")
            client.set_value("Load file", True)
            _notice(client, "50,000,000")
        else:
            data = (folder / "accepted.xyz").read_bytes()
            client.upload("Upload file", "accepted.xyz", data)
            client.wait_for(lambda m: "accepted.xyz" in str(m) and "points shown" in str(m),
                            timeout=120, what="the uploaded cloud")
        time.sleep(1.0)
        return before, proc.memory()["VmHWM"] / MiB
    finally:
        client.close()
        proc.stop()


def _notice(client, text: str) -> None:
    client.wait_for(lambda m: m.get("type") == "NotificationShowMessage"
                    and text in m["props"]["body"], timeout=120, what=text)


def _data(folder: Path) -> None:
    from tests.app.test_limits import laz_bomb
    from tests.helpers import face_cloud

    np.save(folder / "face.npy", face_cloud(20_000, seed=3).xyz())
    laz_bomb(folder / "bomb.laz")
    xyz = face_cloud(400_000, seed=4).xyz()
    np.savetxt(folder / "accepted.xyz", xyz, fmt="%.4f")


def cache_table() -> None:
    from rough_viewer.app.cache import nbytes
    from rough_viewer.app.cloud import LoadedCloud
    from rough_viewer.app.limits import CACHE_BYTES
    from rough_viewer.app.settings import MapSettings
    from rough_viewer.synthetic import demos

    cloud = demos.load_demo("outcrop")
    loaded = LoadedCloud(cloud, max_display=10)
    print(f"\ngrid cache on the demo outcrop ({cloud.n:,} points), budget "
          f"{CACHE_BYTES / MiB:.0f} MiB")
    for g in (0.125, 0.25, 0.5, 1.0, 0.3, 0.02):
        r = loaded.result(MapSettings(cell_size=g))
        p = loaded.prepared(g)
        print(f"  grid {g:<6g} result {nbytes(r) / MiB:6.1f} MiB, membership "
              f"{nbytes(p) / MiB:6.1f} MiB, cache now {loaded.cached_bytes / MiB:6.0f} MiB")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cache", action="store_true", help="also the grid cache on the demo")
    args = ap.parse_args()
    cases = ["refused 200 MiB upload", "64 MiB upload announced as 1 MiB",
             "LAZ bomb, uploaded", "LAZ bomb, Load file", "accepted text upload, 400,000 points"]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        _data(folder)
        size = (folder / "accepted.xyz").stat().st_size / MiB
        print(f"serve process, 20,000 points, --max-upload-mb 16; peak resident memory "
              f"(VmHWM), median of {args.repeat}; accepted upload {size:.1f} MiB")
        for name in cases:
            runs = [_case(folder, name) for _ in range(args.repeat)]
            before = statistics.median(b for b, _ in runs)
            after = statistics.median(a for _, a in runs)
            print(f"  {name:36s} before {before:6.0f} MiB  after {after:6.0f} MiB  "
                  f"(+{after - before:.0f})")
    if args.cache:
        cache_table()


if __name__ == "__main__":
    main()
