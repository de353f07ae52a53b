"""Uploads from the browser, streamed to disk with a size limit.

viser keeps every part of an upload in memory and hands the whole file to the
app as bytes, so one 300 MB upload costs 300 MB of server memory. The app takes
over viser's upload messages (``FileTransferStartUpload``, ``FileTransferPart``)
instead:

- a transfer is refused at its start when the file name's extension is not a
  point-cloud format, the declared size is above ``max_bytes``
  (``--max-upload-mb``), the disk lacks room, or too many uploads are running;
- accepted parts are written straight to a file in a private temporary folder
  (under a generated name; the user's file name is only shown, escaped), in
  order, and the transfer is cut off as soon as it passes its declared size or
  the limit;
- a finished file is handed to the app as an :class:`UploadedFile`, which the
  load job deletes once read; a dropped connection deletes its partial files.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import threading
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import viser
from viser import _messages

from rough_viewer.app import hooks
from rough_viewer.app.files import UploadedFile
from rough_viewer.app.limits import (
    DEFAULT_MAX_UPLOAD_MB,
    MAX_ACTIVE_UPLOADS,
    MAX_REFUSALS,
    MAX_UPLOAD_NAME,
    UPLOAD_DISK_MARGIN,
)
from rough_viewer.app.stage import Stage, stage_of
from rough_viewer.memory import format_bytes

__all__ = ["DEFAULT_MAX_UPLOAD_MB", "UploadedFile", "Uploads", "clean_name"]


@dataclass
class _Transfer:
    client_id: int
    name: str
    suffix: str
    declared: int
    parts: int
    path: Path
    fh: BinaryIO
    next_part: int = 0
    received: int = 0


class Uploads:
    """Receive uploads of the server's upload buttons on disk.

    Parameters
    ----------
    server
        The viser server (its own upload buttons), or a stage (one tab's:
        :mod:`rough_viewer.app.stage`).
    max_bytes
        Largest file accepted, bytes.
    suffixes
        File name extensions accepted (lower case, with the dot).
    refuse
        ``refuse(client_id, message)``: tell one browser its upload was refused.
    folder
        Where files are written (default: a new private temporary folder,
        removed by :meth:`close`).
    """

    def __init__(
        self,
        server: viser.ViserServer | Stage,
        *,
        max_bytes: int,
        suffixes: Iterable[str],
        refuse: Callable[[int, str], None],
        folder: Path | None = None,
    ) -> None:
        stage = stage_of(server)
        self._server = stage.server
        self.max_bytes = int(max_bytes)
        self._suffixes = tuple(s.lower() for s in suffixes)
        self._refuse = refuse
        self._own_folder = folder is None
        if folder is None:
            sweep_stale_uploads(Path(tempfile.gettempdir()))
            self.folder = Path(tempfile.mkdtemp(prefix=owned_prefix()))
        else:
            self.folder = Path(folder)
        self._targets: dict[str, Callable[[UploadedFile], object]] = {}
        self._active: dict[str, _Transfer] = {}
        self._lock = threading.Lock()
        self._count = 0
        self.refused: deque[str] = deque(maxlen=MAX_REFUSALS)
        """Messages of refused uploads, oldest first (the last 100)."""
        stage.replace_handlers(_messages.FileTransferStartUpload, lambda _viser: self._on_start)
        stage.replace_handlers(_messages.FileTransferPart, lambda _viser: self._on_part)
        stage.on_client_disconnect(lambda client: self.drop_client(client.client_id))

    def register(self, handle: viser.GuiUploadButtonHandle,
                 on_file: Callable[[UploadedFile], object]) -> None:
        """Send files uploaded with ``handle`` to ``on_file`` (on viser's event loop:
        it should only queue work)."""
        with self._lock:
            self._targets[hooks.uuid_of(handle)] = on_file

    # ------------------------------------------------------------------ messages
    def _on_start(self, client_id: int, message: _messages.FileTransferStartUpload) -> None:
        name = clean_name(message.filename)
        with self._lock:
            target = self._targets.get(message.source_component_uuid)
            busy = len(self._active)
        if target is None:
            return
        suffix = Path(name).suffix.lower()
        size = message.size_bytes
        reason = None
        if suffix not in self._suffixes:
            reason = (f"{name}: not a point-cloud file (accepted: "
                      f"{' '.join(self._suffixes)})")
        elif not isinstance(size, int) or size < 0 or not isinstance(message.part_count, int) \
                or message.part_count < 0 or message.part_count > max(1, size):
            reason = f"{name}: the browser sent an invalid upload"
        elif size > self.max_bytes:
            reason = (f"{name} is {format_bytes(size)}, more than the upload limit of "
                      f"{format_bytes(self.max_bytes)} (--max-upload-mb)")
        elif busy >= MAX_ACTIVE_UPLOADS:
            reason = f"{name}: {busy} uploads are running already; try again when they end"
        elif shutil.disk_usage(self.folder).free < size + UPLOAD_DISK_MARGIN:
            reason = f"{name}: not enough free disk space on the server"
        if reason is not None:
            self._refused(client_id, message.source_component_uuid, message.transfer_uuid,
                          size if isinstance(size, int) else 0, reason)
            return
        with self._lock:
            self._count += 1
            path = self.folder / f"upload-{self._count}{suffix}"
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
            self._active[message.transfer_uuid] = _Transfer(
                client_id, name, suffix, size, message.part_count, path, os.fdopen(fd, "wb"))
        if message.part_count == 0:
            self._finish(message.transfer_uuid, message.source_component_uuid)

    def _on_part(self, client_id: int, message: _messages.FileTransferPart) -> None:
        with self._lock:
            t = self._active.get(message.transfer_uuid)
        if t is None or t.client_id != client_id:
            return
        content = message.content if isinstance(message.content, bytes) else b""
        if message.part_index != t.next_part:
            self._abort(message.transfer_uuid, f"{t.name}: upload parts arrived out of order")
            return
        if t.received + len(content) > min(t.declared, self.max_bytes):
            self._abort(message.transfer_uuid,
                        f"{t.name}: the upload is larger than announced or than the limit of "
                        f"{format_bytes(self.max_bytes)} (--max-upload-mb)")
            return
        try:
            t.fh.write(content)
        except (OSError, ValueError):  # ValueError: closed meanwhile (the browser left)
            self._abort(message.transfer_uuid, f"{t.name}: the server could not store the upload")
            return
        t.next_part += 1
        t.received += len(content)
        hooks.send_to(self._server, client_id, _messages.FileTransferPartAck(
            source_component_uuid=message.source_component_uuid,
            transfer_uuid=message.transfer_uuid,
            transferred_bytes=t.received, total_bytes=t.declared))
        if t.next_part == t.parts:
            self._finish(message.transfer_uuid, message.source_component_uuid)

    # ------------------------------------------------------------------ endings
    def _finish(self, transfer_uuid: str, source: str | None) -> None:
        with self._lock:
            t = self._active.pop(transfer_uuid, None)
            found = self._targets.get(source or "")
        if t is None:
            return
        t.fh.close()
        if t.received != t.declared or found is None:
            t.path.unlink(missing_ok=True)
            self._refused(t.client_id, None, None, 0,
                          f"{t.name}: {t.received} of {t.declared} bytes arrived")
            return
        found(UploadedFile(t.path, t.name, t.received))

    def _abort(self, transfer_uuid: str, reason: str) -> None:
        with self._lock:
            t = self._active.pop(transfer_uuid, None)
        if t is None:
            return
        t.fh.close()
        t.path.unlink(missing_ok=True)
        self._refused(t.client_id, None, transfer_uuid, t.declared, reason)

    def _refused(self, client_id: int, source: str | None, transfer_uuid: str | None,
                 total: int, reason: str) -> None:
        self.refused.append(reason)
        if transfer_uuid is not None:
            # end the browser's progress bar (it re-enables the button)
            hooks.send_to(self._server, client_id, _messages.FileTransferPartAck(
                source_component_uuid=source, transfer_uuid=transfer_uuid,
                transferred_bytes=total, total_bytes=total))
        self._refuse(client_id, reason)

    def drop_client(self, client_id: int) -> None:
        """Delete the partial uploads of a browser that went away."""
        with self._lock:
            gone = [k for k, t in self._active.items() if t.client_id == client_id]
            transfers = [self._active.pop(k) for k in gone]
        for t in transfers:
            t.fh.close()
            t.path.unlink(missing_ok=True)

    @property
    def active(self) -> int:
        """Uploads being received now."""
        with self._lock:
            return len(self._active)

    def close(self) -> None:
        """Drop running uploads and remove the upload folder (if the app made it)."""
        with self._lock:
            transfers = list(self._active.values())
            self._active.clear()
        for t in transfers:
            t.fh.close()
        if self._own_folder:
            shutil.rmtree(self.folder, ignore_errors=True)


#: The private upload folders' name prefix; the owning server's pid and start follow.
UPLOAD_FOLDER_PREFIX = "rough-viewer-uploads-"
#: A folder whose name names no owner (an older server's) is swept after this long, s.
UNOWNED_AGE_S = 24 * 3600.0


def _process_start(pid: int) -> str | None:
    """A running process's start (clock ticks after boot, from ``/proc``: a pid used
    again by a later process has another), None when none runs or ``/proc`` cannot tell."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = stat[stat.rfind(")") + 2:].split()  # after the command name, which may hold spaces
    return fields[19] if len(fields) > 19 and fields[19].isdigit() else None


def owned_prefix(pid: int | None = None) -> str:
    """The name prefix of an upload folder owned by process ``pid`` (default this one):
    ``rough-viewer-uploads-<pid>-<start>-``, so a later server can tell whether it runs."""
    pid = os.getpid() if pid is None else pid
    return f"{UPLOAD_FOLDER_PREFIX}{pid}-{_process_start(pid) or 0}-"


def sweep_stale_uploads(parent: Path) -> int:
    """Remove the upload folders under ``parent`` that no running server owns: partial
    uploads left by a server that was killed (``kill -9`` runs no clean-up), named for
    a process that no longer runs (or another process under its pid), and folders
    naming no owner older than :data:`UNOWNED_AGE_S`. Returns how many went. Folders
    of running servers, other users' and anything not named like ours are left alone."""
    import time

    gone = 0
    try:
        candidates = [d for d in parent.iterdir() if d.name.startswith(UPLOAD_FOLDER_PREFIX)]
    except OSError:
        return 0
    for d in candidates:
        try:
            if d.is_symlink() or not d.is_dir() or d.stat().st_uid != os.getuid():
                continue
            parts = d.name[len(UPLOAD_FOLDER_PREFIX):].split("-")
            if len(parts) >= 3 and parts[0].isdigit() and parts[1].isdigit() and parts[1] != "0":
                if _process_start(int(parts[0])) == parts[1]:
                    continue  # its server runs
            elif time.time() - d.stat().st_mtime < UNOWNED_AGE_S:
                continue
        except OSError:
            continue
        shutil.rmtree(d, ignore_errors=True)
        gone += not d.exists()
    return gone


def clean_name(name: object) -> str:
    """An upload's file name fit to show: one line, no path separators, at most
    :data:`MAX_UPLOAD_NAME` characters (escape it before putting it in Markdown)."""
    text = "".join(ch if ch.isprintable() else " " for ch in str(name))
    text = text.replace("/", "_").replace("\\", "_").strip() or "upload"
    return text if len(text) <= MAX_UPLOAD_NAME else text[: MAX_UPLOAD_NAME - 1] + "…"
