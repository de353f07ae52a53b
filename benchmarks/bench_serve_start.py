"""How soon ``rough-viewer serve`` gives its address, and how soon its first map is ready.

    PYTHONPATH=. python benchmarks/bench_serve_start.py [INPUT ...] [--repeat 5]

For the demo outcrop and each INPUT, ``serve`` is started ``--repeat`` times as a
user starts it (a fresh process); printed: the seconds from the command to the
``listening at URL`` line (the address: issue 35's target is 2 s) and to the
``N points, open URL`` line (the first map ready), medians and ranges.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import threading
import time


def one_start(inputs: list[str]) -> tuple[float, float]:
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "rough_viewer", "serve", *inputs,
                             "--port", "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, bufsize=1)
    listening: list[float] = []

    def watch_stderr() -> None:
        assert proc.stderr is not None
        for line in proc.stderr:
            if "listening at http" in line and not listening:
                listening.append(time.perf_counter() - t0)

    threading.Thread(target=watch_stderr, daemon=True).start()
    ready = float("nan")
    assert proc.stdout is not None
    for line in proc.stdout:
        if ", open http" in line:
            ready = time.perf_counter() - t0
            break
    proc.terminate()
    try:
        proc.wait(20)
    except subprocess.TimeoutExpired:
        proc.kill()
    return (listening[0] if listening else float("nan")), ready


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("inputs", nargs="*", help="point-cloud files (each run on its own)")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores; load {os.getloadavg()[0]:.1f}", flush=True)
    for case in [[], *([p] for p in args.inputs)]:
        runs = [one_start(case) for _ in range(args.repeat)]
        listen = [r[0] for r in runs]
        ready = [r[1] for r in runs]
        name = case[0] if case else "demo outcrop"
        print(f"{name}: address {statistics.median(listen):.2f} s "
              f"({min(listen):.2f}-{max(listen):.2f}), first map ready "
              f"{statistics.median(ready):.1f} s ({min(ready):.1f}-{max(ready):.1f}), "
              f"medians of {len(runs)}", flush=True)


if __name__ == "__main__":
    main()
