"""Time, size and server memory of each download of the app's Export folder.

    PYTHONPATH=. python benchmarks/bench_app_export.py INPUT [--grid G] [--repeat 3]
    PYTHONPATH=. python benchmarks/bench_app_export.py --demo outcrop

Each repeat starts a fresh ``rough-viewer serve`` process on INPUT; a protocol-level
client (tests/app/protocol.py, the browser's WebSocket messages) presses each download
button in turn and waits until the whole file has arrived. For each download it prints
the medians over the repeats of: seconds from the press to the last byte received,
the file size, and the rise of the server's peak resident memory during that
download (``VmHWM`` after, minus ``VmRSS`` before; the peak is reset before each
download through ``/proc/PID/clear_refs``). Memory an earlier download freed is
reused by the next without counting, so measure one download alone with ``--only``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

MiB = 1 << 20

#: (what, format control and value or None, button label, part of the file name)
DOWNLOADS = [
    ("LAZ points", ("Points file", "LAZ"), "Download points", "_points.laz"),
    ("LAS points", ("Points file", "LAS"), "Download points", "_points.las"),
    ("PLY points", ("Points file", "PLY"), "Download points", "_points.ply"),
    ("CSV cell table", ("Cell table", "CSV"), "Download cell table", "_cells.csv"),
    ("Parquet cell table", ("Cell table", "Parquet"), "Download cell table", "_cells.parquet"),
    ("figures (HTML, ZIP)", None, "Download figure", "_figures_html.zip"),
    ("report (HTML)", None, "Download report (HTML)", "_report.html"),
    ("view (JSON)", None, "Download view (JSON)", ".view.json"),
]


def _reset_peak(pid: int) -> None:
    with open(f"/proc/{pid}/clear_refs", "w") as fh:
        fh.write("5")  # resets VmHWM to the current RSS (Linux >= 4.0)


def one_run(args: list[str], only: list[str]) -> dict[str, tuple[float, int, float]]:
    from tests.app.protocol import ProtocolClient
    from tests.app.serve_process import ServeProcess

    proc = ServeProcess(*args, "--no-token", timeout=600)
    client = ProtocolClient(proc.port, "/", timeout=60)
    out: dict[str, tuple[float, int, float]] = {}
    try:
        client.uuid("Download view (JSON)")
        time.sleep(2.0)
        for what, choice, label, part in DOWNLOADS:
            if only and what not in only:
                continue
            if choice is not None:
                client.set_value(*choice)
                time.sleep(0.5)
            seen = set(client.downloads())
            before = proc.memory()["VmRSS"]
            _reset_peak(proc.proc.pid)
            t0 = time.perf_counter()
            client.press(label)
            end = t0 + 600
            name = data = None
            while time.perf_counter() < end:
                got = {n: d for n, d in client.downloads().items() if part in n and n not in seen}
                if got:
                    name, data = next(iter(got.items()))
                    break
                time.sleep(0.02)
            if data is None:
                raise TimeoutError(f"{what}: no download")
            seconds = time.perf_counter() - t0
            peak = proc.memory()["VmHWM"]
            out[what] = (seconds, len(data), (peak - before) / MiB)
            with client._lock:  # the client keeps every message: drop the parts
                client.messages = [m for m in client.messages
                                   if m.get("type") != "FileTransferPart"]
        out["_server"] = (0.0, 0, proc.memory()["VmHWM"] / MiB)
    finally:
        client.close()
        proc.stop()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("input", nargs="?")
    ap.add_argument("--demo")
    ap.add_argument("--grid", default="2")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--only", action="append", default=[], metavar="WHAT",
                    help="only this download (e.g. 'LAS points'; repeatable): measured alone "
                    "in a fresh process, its peak is not hidden by memory an earlier one freed")
    a = ap.parse_args()
    args = [a.input] if a.input else ["--demo", a.demo or "outcrop"]
    args += ["--grid", a.grid]
    runs = [one_run(args, a.only) for _ in range(a.repeat)]
    name = Path(a.input).name if a.input else f"demo {a.demo or 'outcrop'}"
    print(f"{name}, grid {a.grid} m, medians of {a.repeat} fresh serve processes")
    print(f"{'download':22s} {'seconds':>8s} {'size':>11s} {'peak + (MiB)':>13s}")
    for what, *_ in DOWNLOADS:
        if a.only and what not in a.only:
            continue
        s = statistics.median(r[what][0] for r in runs)
        size = statistics.median(r[what][1] for r in runs)
        peak = statistics.median(r[what][2] for r in runs)
        print(f"{what:22s} {s:8.2f} {size / MiB:8.2f} MiB {peak:13.0f}")
    print(f"server peak over the run: {statistics.median(r['_server'][2] for r in runs):.0f} MiB")


if __name__ == "__main__":
    main()
