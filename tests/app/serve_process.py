"""``rough-viewer serve`` as a real process: start it, read the URL it prints,
measure its memory, stop it."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from urllib.parse import urlsplit

URL = re.compile(r"open (http://\S+)")


class ServeProcess:
    """``rough-viewer serve ARGS...`` in a child process (``--port 0`` added)."""

    def __init__(self, *args: str, timeout: float = 120.0) -> None:
        cmd = [sys.executable, "-c", "from rough_viewer.cli import main; raise SystemExit(main())",
               "serve", *args, "--port", "0"]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, bufsize=1)
        self.stderr: list[str] = []
        threading.Thread(target=self._drain, daemon=True).start()
        end = time.time() + timeout
        self.url = ""
        assert self.proc.stdout is not None
        while time.time() < end:
            line = self.proc.stdout.readline()
            if not line:
                if self.proc.poll() is not None:
                    raise RuntimeError(f"serve exited: {''.join(self.stderr)}")
                continue
            m = URL.search(line)
            if m:
                self.url = m.group(1)
                break
        if not self.url:
            self.stop()
            raise TimeoutError("serve printed no URL")
        parts = urlsplit(self.url)
        self.port = int(parts.port or 80)
        self.path = parts.path

    def _drain(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self.stderr.append(line)

    def memory(self) -> dict[str, int]:
        """``VmRSS`` and ``VmHWM`` (peak) of the process, bytes."""
        out = {}
        with open(f"/proc/{self.proc.pid}/status") as fh:
            for line in fh:
                key, _, rest = line.partition(":")
                if key in ("VmRSS", "VmHWM"):
                    out[key] = int(rest.split()[0]) * 1024
        return out

    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self) -> None:
        if self.proc.poll() is None:
            os.kill(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
