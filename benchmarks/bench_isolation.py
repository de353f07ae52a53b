"""What decoding in a child process costs (issue 21): ``load_points`` of the same
files read in this process, in a child started on demand ("cold", as a first read
in a command run without ``warm``), and in a spare child started ahead ("warm": what
``serve`` and the command line do, the child's start-up overlapping other work).

    PYTHONPATH=. python benchmarks/bench_isolation.py [FILE ...] [--repeat 7]

Default files: the bundled demo (demo_data/outcrop.laz, 2.0 M points) and the
airborne LAZ of /work/shared/data/santacruz_als_laz (574 k points) where present.
The decode cache is off (every read decodes). Prints the median seconds of each way
over ``--repeat`` reads, and the extra time and share of isolation against the
in-process decode.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

DEFAULTS = [Path("demo_data/outcrop.laz"),
            *sorted(Path("/work/shared/data/santacruz_als_laz").glob("*.laz"))]


def _time(path: Path, *, isolated: bool, warm: bool) -> float:
    from rough_viewer.io import load_points
    from rough_viewer.io.sandbox import isolate

    os.environ["ROUGH_VIEWER_ISOLATE"] = "1" if isolated else "0"
    if isolated and warm:
        isolate.warm()
        time.sleep(3.0)  # the spare has imported its libraries (others' work, in practice)
    t0 = time.perf_counter()
    cloud = load_points(path, cache=False)
    seconds = time.perf_counter() - t0
    assert cloud.n > 0
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="*", type=Path)
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    from rough_viewer.io import load_points
    from rough_viewer.io.sandbox import isolate

    files = args.files or [p for p in DEFAULTS if p.exists()]
    print(f"cpus {os.cpu_count()}, isolation available: {isolate.available()}")
    print(f"{'file':<44} {'points':>10} {'in-process s':>12} {'cold s':>8} {'warm s':>8} "
          f"{'warm extra':>11} {'cold extra':>11}")
    for path in files:
        n = load_points(path, cache=False).n
        got: dict[str, list[float]] = {"in": [], "cold": [], "warm": []}
        for _ in range(args.repeat):  # interleaved, so that load on the machine hits all
            got["in"].append(_time(path, isolated=False, warm=False))
            isolate._close_spare()
            got["cold"].append(_time(path, isolated=True, warm=False))
            got["warm"].append(_time(path, isolated=True, warm=True))
        med = {k: statistics.median(v) for k, v in got.items()}
        base = med["in"]
        print(f"{path.name[:44]:<44} {n:>10,} {base:>12.3f} {med['cold']:>8.3f} "
              f"{med['warm']:>8.3f} {med['warm'] - base:>+8.3f} s {med['cold'] - base:>+8.3f} s"
              f"   ({100 * (med['warm'] - base) / base:+.0f} % warm, "
              f"{100 * (med['cold'] - base) / base:+.0f} % cold)")
    os.environ.pop("ROUGH_VIEWER_ISOLATE", None)


if __name__ == "__main__":
    main()
