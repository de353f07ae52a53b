"""Peak memory (RSS) and time of ``rough-viewer report`` on real scans and on a
sparse two-patch cloud (issue 11).

Each run is a fresh ``python -m rough_viewer report`` process; its peak resident
set size comes from ``os.wait4`` (the kernel's ``ru_maxrss`` of that process alone).
Prints the median time and the median and largest peak RSS over ``--repeat`` runs.

Cases:

- every ``*.laz`` in ``--laz-dir`` (default ``../shared/data/santacruz_als_laz``),
  ``report`` with the default grids (from the point spacing); target < 3 GB;
- two patches 1.5 km apart (each 10 m x 10 m, points every 1.25 cm, a rough
  surface), ``report --grid 0.05``: along x (an outcrop in two parts) and
  diagonally (the face-plane image between them cannot fit and is refused, the
  rest of the report stands); target < 2.5 GB.

    flock /tmp/rough_viewer_heavy.lock python benchmarks/bench_real_scans.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_LAZ_DIR = ROOT.parent.parent / "shared" / "data" / "santacruz_als_laz"


def run_once(argv: list[str]) -> tuple[float, float, int, str]:
    """(seconds, peak RSS in bytes, exit status, stderr) of one command."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    assert proc.stderr is not None
    err = proc.stderr.read().decode(errors="replace")
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return time.perf_counter() - t0, usage.ru_maxrss * 1024.0, proc.returncode, err


def measure(label: str, argv: list[str], repeat: int, target_gib: float) -> None:
    times, peaks = [], []
    err = ""
    for _ in range(repeat):
        t, peak, rc, err = run_once(argv)
        if rc != 0:
            print(f"{label}: exit status {rc}: {err.strip().splitlines()[-1:]}")
            return
        times.append(t)
        peaks.append(peak)
    gib = 2.0**30
    ok = "ok" if max(peaks) < target_gib * gib else "OVER TARGET"
    print(f"{label}\n  time median {statistics.median(times):7.2f} s; peak RSS median "
          f"{statistics.median(peaks) / gib:5.2f} GiB, max {max(peaks) / gib:5.2f} GiB "
          f"(target < {target_gib:g} GiB: {ok})")
    notes = [line for line in err.splitlines() if "warning" in line or "no maps" in line]
    for line in notes[:4]:
        print(f"  {line[:160]}")


def two_patches(path: Path, offset: np.ndarray, spacing: float = 0.0125, side: float = 10.0) -> int:
    """Write two rough 10 m patches, ``offset`` metres apart, as an (N, 3) .npy."""
    rng = np.random.default_rng(0)
    n = int(round(side / spacing))
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    x = (i.ravel() + rng.uniform(-0.3, 0.3, i.size)) * spacing
    y = (j.ravel() + rng.uniform(-0.3, 0.3, j.size)) * spacing
    z = 0.05 * np.sin(x * 1.3) * np.cos(y * 0.7) + 0.003 * rng.standard_normal(x.size)
    patch = np.column_stack([x, y, z]) + np.array([512_000.0, 4_170_000.0, 100.0])
    xyz = np.vstack([patch, patch + offset])
    np.save(path, xyz)
    return int(xyz.shape[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--laz-dir", type=Path, default=DEFAULT_LAZ_DIR)
    ap.add_argument("--skip-laz", action="store_true")
    ap.add_argument("--skip-patches", action="store_true")
    args = ap.parse_args()
    py = [sys.executable, "-m", "rough_viewer"]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "r.html"
        cache = Path(tmp) / "cache"
        os.environ["ROUGH_VIEWER_CACHE"] = str(cache)
        if not args.skip_laz:
            files = sorted(args.laz_dir.glob("*.laz"))
            if not files:
                print(f"no .laz files in {args.laz_dir}")
            for f in files:
                measure(f"report, default grids: {f.name} (first run decodes, later runs "
                        "use the decode cache)",
                        [*py, "report", str(f), "--out", str(out), "--force", "--quiet"],
                        args.repeat, 3.0)
                measure(f"report, the paper's grids 1 0.5 0.25 0.125 m: {f.name}",
                        [*py, "report", str(f), "--grid", "1", "--grid", "0.5", "--grid", "0.25",
                         "--grid", "0.125", "--out", str(out), "--force", "--quiet"],
                        args.repeat, 3.0)
        if not args.skip_patches:
            for name, offset in (("along x", np.array([1500.0, 0.0, 0.0])),
                                 ("diagonal", np.array([1060.66, 1060.66, 0.0]))):
                cloud = Path(tmp) / f"patches_{name.replace(' ', '_')}.npy"
                n = two_patches(cloud, offset)
                measure(f"report --grid 0.05: two 10 m patches 1.5 km apart ({name}), "
                        f"{n:,} points",
                        [*py, "report", str(cloud), "--grid", "0.05", "--out", str(out),
                         "--force", "--quiet"], args.repeat, 2.5)


if __name__ == "__main__":
    main()
