"""A class on one ``rough-viewer serve --classroom``: every tab its own analysis.

    PYTHONPATH=. python benchmarks/bench_classroom.py [INPUT] [--tabs 12 30] [--repeat 3]

A real ``serve --classroom`` process on the demo outcrop (2 M points) and raw
WebSocket tabs (tests/app/protocol.py, viser's own protocol: what a browser sends
and receives, without drawing). For each class size:

1. the tabs connect (students' address) and each waits for its first map;
2. every tab changes its grid and its model at once (tab *i*: preset *i* mod 4,
   ODR or OLS by parity); a tab's answer is the time until its own status line
   names its own model and grid; printed: median and slowest answer, and whether
   each tab ended showing its own choice;
3. one tab changes again while the others are watched for 3 s: messages the others
   received (should be 0);
4. the server's resident memory (its process and its reader child) before the tabs
   and with them;
5. the teacher (teacher's address) chooses a grid and model and presses *Send my
   view to everyone*: the time until every student's status line shows them.

Each class size runs ``--repeat`` times on a fresh server; medians are printed.
The issue's targets (12 tabs): median answer <= 3 s, every answer <= 15 s, nothing
to the other tabs, memory growth <= 1 GB, every student on the teacher's view
within 15 s.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import threading
import time

from tests.app.protocol import ProtocolClient

GiB = 1 << 30
STATUS = re.compile(r"(ODR|OLS|hybrid|e_OLS), grid ([0-9.]+) m")


class Server:
    """``rough-viewer serve --classroom`` (the demo, or ``inputs``) in a child process."""

    def __init__(self, inputs: list[str] | None = None) -> None:
        cmd = [sys.executable, "-m", "rough_viewer", "serve", *(inputs or []), "--classroom",
               "--port", "0", "--max-connections", "64"]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, bufsize=1)
        threading.Thread(target=lambda: [None for _ in self.proc.stderr or ()],
                         daemon=True).start()
        self.student = self.teacher = ""
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            if line.startswith("open "):
                self.student = line.split()[1]
            elif line.startswith("teacher "):
                self.teacher = line.split()[1]
                break
        m = re.match(r"http://127\.0\.0\.1:(\d+)(/t/[^/]+/)", self.student)
        assert m and self.teacher, "serve printed no addresses"
        self.port = int(m.group(1))
        self.path = m.group(2)
        self.teacher_path = re.sub(r"^http://[^/]+", "", self.teacher)

    def rss(self) -> int:
        """Resident bytes of the server and its children (the reader sandbox)."""
        pids = [self.proc.pid]
        try:
            out = subprocess.run(["pgrep", "-P", str(self.proc.pid)], capture_output=True,
                                 text=True).stdout
            pids += [int(p) for p in out.split()]
        except OSError:
            pass
        total = 0
        for pid in pids:
            try:
                with open(f"/proc/{pid}/status") as fh:
                    for line in fh:
                        if line.startswith("VmRSS:"):
                            total += int(line.split()[1]) * 1024
            except OSError:
                continue
        return total

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(15)
        except subprocess.TimeoutExpired:
            self.proc.kill()


def status_of(tab: ProtocolClient) -> tuple[str, float] | None:
    """(model, grid m) the tab's status line names last (None before its first map)."""
    with tab._lock:
        messages = list(tab.messages)
    for m in reversed(messages):
        text = None
        for part in ("updates", "props"):
            if isinstance(m.get(part), dict):
                text = m[part].get("_markdown", m[part].get("content"))
        if isinstance(text, str):
            found = STATUS.search(text)
            if found:
                return found.group(1), float(found.group(2))
    return None


def grid_options(tab: ProtocolClient) -> list[str]:
    msg = tab.wait_for(lambda m: isinstance(m.get("props"), dict)
                       and m["props"].get("label") == "Grid size (m)", 60, "the grid control")
    return [o for o in msg["props"]["options"] if o != "free"]


def wait(cond, timeout: float, what: str) -> float:
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < timeout:
        if cond():
            return time.perf_counter() - t0
        time.sleep(0.05)
    raise TimeoutError(what)


def quiet(tabs: list[ProtocolClient], still_s: float, timeout: float) -> None:
    """Wait until no tab has received anything for ``still_s`` (at most ``timeout``)."""
    end = time.perf_counter() + timeout
    counts, since = [len(t.messages) for t in tabs], time.perf_counter()
    while time.perf_counter() < end and time.perf_counter() - since < still_s:
        time.sleep(0.1)
        now = [len(t.messages) for t in tabs]
        if now != counts:
            counts, since = now, time.perf_counter()


def one_class(n: int, inputs: list[str] | None = None) -> dict[str, float]:
    server = Server(inputs)
    tabs: list[ProtocolClient] = []
    try:
        time.sleep(2.0)
        rss0 = server.rss()
        t0 = time.perf_counter()
        for _ in range(n):
            tabs.append(ProtocolClient(server.port, server.path, timeout=30.0))
        wait(lambda: all(status_of(t) for t in tabs), 600, "every tab's first map")
        first = time.perf_counter() - t0
        options = grid_options(tabs[0])
        want = []
        for i, _tab in enumerate(tabs):
            want.append(("OLS" if i % 2 else "ODR", options[i % len(options)]))
        sent = time.perf_counter()
        for tab, (model, grid) in zip(tabs, want, strict=True):
            tab.set_value("Grid size (m)", grid)
            tab.set_value("Model", model)
        answers: list[float] = [float("nan")] * n
        end = sent + 120.0
        while time.perf_counter() < end and any(a != a for a in answers):
            for i, (tab, (model, grid)) in enumerate(zip(tabs, want, strict=True)):
                if answers[i] != answers[i]:
                    st = status_of(tab)
                    if st is not None and st[0] == model and abs(st[1] - float(grid)) < 1e-9:
                        answers[i] = time.perf_counter() - sent
            time.sleep(0.05)
        own = sum(1 for a in answers if a == a)
        rss1 = server.rss()
        # one tab changes once every tab is quiet; what do the others receive?
        quiet(tabs, 2.0, 180.0)
        counts = [len(t.messages) for t in tabs]
        tabs[0].set_value("Model", "OLS" if want[0][0] == "ODR" else "ODR")
        time.sleep(3.0)
        first_ids = {m.get("uuid") for m in tabs[0].messages if m.get("uuid")}
        later = [m for t, c in zip(tabs[1:], counts[1:], strict=True) for m in t.messages[c:]]
        leaked = sum(1 for m in later if m.get("uuid") in first_ids)
        theirs = [m for m in later if m.get("uuid") not in first_ids]
        if theirs:  # their own work that was still going on (panels, idle precomputing)
            what = sorted({f"{m.get('type')} {sorted((m.get('updates') or {}).keys())}"
                           for m in theirs})
            print(f"  the other tabs' own messages meanwhile: {len(theirs)} "
                  f"({'; '.join(what)})",
                  flush=True)
        # the teacher sends a view
        teacher = ProtocolClient(server.port, server.teacher_path, timeout=30.0)
        wait(lambda: status_of(teacher) is not None, 300, "the teacher's first map")
        grid = options[-2] if len(options) > 1 else options[0]
        teacher.set_value("Grid size (m)", grid)
        teacher.set_value("Model", "OLS")
        wait(lambda: status_of(teacher) == ("OLS", float(grid)), 300, "the teacher's map")
        pushed = time.perf_counter()
        teacher.press("Send my view to everyone")
        try:
            push = wait(lambda: all(status_of(t) == ("OLS", float(grid)) for t in tabs), 120,
                        "every student on the teacher's view")
        except TimeoutError:
            push = float("inf")
        del pushed
        teacher.close()
        done = [a for a in answers if a == a]
        return {"tabs": n, "first_maps_s": first,
                "median_answer_s": statistics.median(done) if done else float("nan"),
                "slowest_answer_s": max(done) if done else float("nan"),
                "own_choice": own, "leaked_messages": leaked,
                "rss_before_gib": rss0 / GiB, "rss_with_tabs_gib": rss1 / GiB,
                "growth_gib": (rss1 - rss0) / GiB, "teacher_push_s": push}
    finally:
        for t in tabs:
            try:
                t.close()
            except Exception:  # noqa: BLE001 - a closed socket is fine here
                pass
        server.stop()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tabs", type=int, nargs="+", default=[12, 30])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("inputs", nargs="*", help="a point-cloud file instead of the demo")
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores; load {os.getloadavg()[0]:.1f}", flush=True)
    for n in args.tabs:
        runs = [one_class(n, args.inputs) for _ in range(args.repeat)]
        for r in runs:
            print("  run: " + ", ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}"
                                        for k, v in r.items()), flush=True)
        keys = [k for k in runs[0] if k != "tabs"]
        med = {k: statistics.median(float(r[k]) for r in runs) for k in keys}
        print(f"{n} tabs, medians of {len(runs)}: " + ", ".join(
            f"{k} {v:.3g}" for k, v in med.items()), flush=True)


if __name__ == "__main__":
    main()
