"""Who may connect: an Origin check and an access token on viser's WebSocket.

A server on 127.0.0.1 is reachable by every web page the user opens and by every
local user. Like Jupyter's token and Bokeh's ``--allow-websocket-origin``, the app
refuses a WebSocket handshake unless

1. its ``Origin`` header is the server's own (``http://127.0.0.1:PORT``,
   ``http://localhost:PORT``, ``http://[::1]:PORT``, the ``--host`` address, and
   for ``--host 0.0.0.0`` this machine's names and addresses) or one given with
   ``--allow-origin``. A page from another origin (another port counts) is
   refused; browsers always send ``Origin`` and pages cannot forge it. A
   handshake without ``Origin`` comes from a program, not a page; the token
   decides for it.
2. its path carries the token: the page lives at ``/t/<token>/`` and viser's
   client opens its WebSocket on the page's path, so the URL ``serve`` prints
   opens the app as before, and nothing else does. ``--no-token`` turns the
   token off for a trusted network.

Plain HTTP requests outside ``/t/<token>/`` get a short page saying the URL with
the token is needed (the client page itself holds no data; the data flows only
through the WebSocket).

What each browser may cost is bounded too: at most ``max_connections``
WebSocket connections are open at once (``serve --max-connections``; more are
refused with 503), and a connection whose client stops reading is closed
(:meth:`Gate.backlog_check`): when its unsent bytes stay above
:data:`STALL_BYTES` for :data:`STALL_SECONDS` without the client taking any, or
exceed :data:`MAX_UNSENT_BYTES` at any time. A browser that reads slowly keeps
taking bytes and is never closed; one that comes back reconnects and gets the
scene again.
"""

from __future__ import annotations

import hmac
import secrets
import socket
import sys
import threading
import time
import weakref
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import urlsplit

import viser
from websockets.asyncio.server import ServerConnection
from websockets.http11 import Request, Response

from rough_viewer.app import hooks
from rough_viewer.app.limits import MAX_REFUSALS
from rough_viewer.memory import format_bytes
from rough_viewer.vocabulary import InputError

#: URL path prefix of the app when a token is used: ``/t/<token>/``.
TOKEN_PREFIX = "/t/"

#: WebSocket connections open at once, by default (``serve --max-connections``).
DEFAULT_MAX_CONNECTIONS = 32
#: A connection whose unsent bytes stay above this ...
STALL_BYTES = 1 << 20
#: ... for this long, without the client taking any, is closed (seconds).
STALL_SECONDS = 20.0
#: A connection with more unsent bytes than this is closed at once (the demo's
#: whole scene is about 80 MiB).
MAX_UNSENT_BYTES = 1 << 30

_LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")
_WILDCARD_HOSTS = ("", "0.0.0.0", "::")

_NEEDS_TOKEN_PAGE = b"""<!doctype html><meta charset="utf-8"><title>rough-viewer</title>
<p>This rough-viewer server needs the address that <code>rough-viewer serve</code>
printed when it started (it ends in <code>/t/&lt;token&gt;/</code>).</p>
"""


def new_token() -> str:
    """A random access token (32 URL-safe characters, 192 bits)."""
    return secrets.token_urlsafe(24)


def normalise_origin(origin: str) -> str:
    """``scheme://host[:port]`` in lower case, without a trailing slash.

    Raises InputError for a value that is not an http(s) origin.
    """
    text = origin.strip().rstrip("/")
    parts = urlsplit(text)
    if parts.scheme not in ("http", "https") or not parts.netloc or parts.path or \
            parts.query or parts.fragment or "@" in parts.netloc:
        raise InputError(f"--allow-origin wants an origin like http://host:8080, got {origin!r}")
    return f"{parts.scheme}://{parts.netloc}".lower()


def own_origins(host: str, port: int) -> frozenset[str]:
    """The origins of pages this server serves itself (see the module docstring)."""
    names = set(_LOOPBACK_NAMES)
    if host not in _WILDCARD_HOSTS:
        names.add(f"[{host}]" if ":" in host and not host.startswith("[") else host)
    else:
        for name in {socket.gethostname(), socket.getfqdn()}:
            names.add(name)
            try:
                infos = socket.getaddrinfo(name, None)
            except OSError:
                continue
            for info in infos:
                addr = str(info[4][0])
                names.add(f"[{addr}]" if ":" in addr else addr)
    out = set()
    for name in names:
        out.add(f"http://{name}:{port}".lower())
        if port == 80:
            out.add(f"http://{name}".lower())
    return frozenset(out)


@dataclass(frozen=True)
class Refusal:
    """A refused request (kept for the log and the tests)."""

    reason: str
    origin: str | None
    path: str


@dataclass
class Gate:
    """The check in front of viser's HTTP server and WebSocket (see :func:`guard`).

    Attributes
    ----------
    token
        The access token, or None (``--no-token``).
    origins
        Origins whose pages may open the WebSocket.
    refused
        The last refused WebSocket handshakes (at most 100).
    """

    token: str | None
    origins: frozenset[str]
    log: bool = False
    teacher_token: str | None = None
    """The teacher's token of ``serve --classroom`` (None: one token for everyone);
    the page at ``/t/<teacher_token>/`` opens the teacher's tab."""
    refused: deque[Refusal] = field(default_factory=lambda: deque(maxlen=MAX_REFUSALS))
    max_connections: int = DEFAULT_MAX_CONNECTIONS
    """WebSocket connections open at once; more are refused."""
    stall_bytes: int = STALL_BYTES
    stall_seconds: float = STALL_SECONDS
    max_unsent: int = MAX_UNSENT_BYTES
    shed: deque[str] = field(default_factory=lambda: deque(maxlen=MAX_REFUSALS))
    """Why connections were closed for not reading (the last 100)."""
    count: Callable[[], int] | None = None
    """Open WebSocket connections now (set by :func:`guard`)."""
    _admitted: weakref.WeakSet[ServerConnection] = field(default_factory=weakref.WeakSet)
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _backlog: weakref.WeakKeyDictionary[ServerConnection, tuple[int, float]] = field(
        default_factory=weakref.WeakKeyDictionary)
    _teachers: weakref.WeakSet[ServerConnection] = field(default_factory=weakref.WeakSet)

    @property
    def path(self) -> str:
        """URL path of the app: ``/t/<token>/``, or ``/`` without a token."""
        return f"{TOKEN_PREFIX}{self.token}/" if self.token else "/"

    @property
    def teacher_path(self) -> str | None:
        """URL path of the teacher's page (None without a teacher's token)."""
        return f"{TOKEN_PREFIX}{self.teacher_token}/" if self.teacher_token else None

    def url(self, host: str, port: int, *, teacher: bool = False) -> str:
        """The address to open (loopback when listening on every interface);
        ``teacher``: the teacher's address (ValueError without a teacher's token)."""
        shown = "127.0.0.1" if host in _WILDCARD_HOSTS else host
        if ":" in shown and not shown.startswith("["):
            shown = f"[{shown}]"
        path = self.teacher_path if teacher else self.path
        if path is None:
            raise ValueError("this server has no teacher's token")
        return f"http://{shown}:{port}{path}"

    def is_teacher(self, connection: ServerConnection | None) -> bool:
        """The WebSocket ``connection`` came with the teacher's token."""
        if connection is None:
            return False
        with self._lock:
            return connection in self._teachers

    def _tokens(self) -> list[str]:
        return [t for t in (self.token, self.teacher_token) if t]

    def _given(self, path: str) -> str:
        path = path.partition("?")[0].rstrip("/")
        return path[len(TOKEN_PREFIX):] if path.startswith(TOKEN_PREFIX) else ""

    def _teacher_given(self, request: Request) -> bool:
        return self.teacher_token is not None and hmac.compare_digest(
            self._given(request.path).encode(), self.teacher_token.encode())

    # ------------------------------------------------------------------ checks
    def websocket_refusal(self, request: Request) -> str | None:
        """Why a WebSocket handshake is refused, or None to let it through."""
        origins = request.headers.get_all("Origin")  # .get() raises on a repeated one
        if len(origins) > 1:
            return "origin not allowed"
        if origins and origins[0].strip().rstrip("/").lower() not in self.origins:
            return "origin not allowed"
        if self.token is not None:
            given = self._given(request.path).encode()
            # every token compared (no early exit: the time taken tells nothing)
            matches = [hmac.compare_digest(given, t.encode()) for t in self._tokens()]
            if not any(matches):
                return "missing or wrong token"
        return None

    def backlog_check(self, connection: ServerConnection, unsent: int, *,
                      now: float | None = None) -> str | None:
        """Why ``connection`` (with ``unsent`` bytes not yet taken by its client) must be
        closed, or None: above :attr:`max_unsent`, or above :attr:`stall_bytes` with
        nothing taken for :attr:`stall_seconds`."""
        t = time.monotonic() if now is None else now
        reason = None
        if unsent > self.max_unsent:
            reason = (f"{format_bytes(unsent)} unsent, more than the "
                      f"{format_bytes(self.max_unsent)} a connection may hold")
        elif unsent <= self.stall_bytes:
            self._backlog.pop(connection, None)
        else:
            last = self._backlog.get(connection)
            if last is None or last[0] != unsent:  # it took some (or more was sent)
                self._backlog[connection] = (unsent, t)
            elif t - last[1] >= self.stall_seconds:
                reason = (f"the client stopped reading ({format_bytes(unsent)} unsent for "
                          f"{t - last[1]:.0f} s)")
        if reason is not None:
            self._backlog.pop(connection, None)
            self.shed.append(reason)
            if self.log:
                print(f"rough-viewer: closed a connection: {reason}", file=sys.stderr,
                      flush=True)
        return reason

    def admitted(self, connection: ServerConnection) -> bool:
        with self._lock:
            return connection in self._admitted

    def wrap(self, original: hooks.ProcessRequest | None) -> hooks.ProcessRequest:
        """The hook that runs before viser's own for every request."""

        def process_request(connection: ServerConnection, request: Request) -> Any:
            if "websocket" in " ".join(request.headers.get_all("Upgrade")).lower():
                reason = self.websocket_refusal(request)
                if reason is not None:
                    return self._refuse(reason, request)
                if self.count is not None and self.count() >= self.max_connections:
                    return self._refuse(
                        f"too many connections (this server allows {self.max_connections}; "
                        "close another tab)", request, status=503)
                with self._lock:
                    self._admitted.add(connection)
                    if self._teacher_given(request):
                        self._teachers.add(connection)
                return None
            with self._lock:
                self._admitted.add(connection)
            path = request.path
            if self.token is not None:
                prefix = self.path
                teacher = self.teacher_path
                if teacher is not None and path.startswith(teacher.rstrip("/")):
                    prefix = teacher
                if path.partition("?")[0] == prefix.rstrip("/"):
                    return _redirect(prefix)
                if not path.startswith(prefix):
                    return hooks.http_response(403, "Forbidden", _NEEDS_TOKEN_PAGE,
                                               "text/html; charset=utf-8")
                path = "/" + path[len(prefix):]
            response = None if original is None else original(
                connection, Request(path=path, headers=request.headers))
            if response is None:  # never let a plain request become a handshake
                return hooks.http_response(404, "Not Found", b"not found", "text/plain")
            return response

        return process_request

    def _refuse(self, reason: str, request: Request, *, status: int = 403) -> Response:
        origin = ", ".join(request.headers.get_all("Origin"))[:200] or None
        path = request.path.partition("?")[0]
        for token in self._tokens():
            if token in path:
                path = path.replace(token, "<token>")
        self.refused.append(Refusal(reason, origin, path))
        if self.log:
            hint = (" (allow it with --allow-origin)" if reason.startswith("origin") else "")
            print(f"rough-viewer: refused a connection from origin {origin or '(none)'}: "
                  f"{reason}{hint}", file=sys.stderr, flush=True)
        return hooks.http_response(status, "Forbidden" if status == 403 else "Service Unavailable",
                                   reason.encode(), "text/plain")


def _redirect(location: str) -> Response:
    from websockets.datastructures import Headers

    return Response(302, "Found", Headers({"Location": location, "Content-Length": "0"}), b"")


def guard(
    server: viser.ViserServer,
    *,
    token: str | None,
    allow_origins: Iterable[str] = (),
    host: str | None = None,
    log: bool = False,
    max_connections: int = DEFAULT_MAX_CONNECTIONS,
    teacher_token: str | None = None,
) -> Gate:
    """Put the Origin check and the token in front of a running viser server.

    Parameters
    ----------
    server
        A started :class:`viser.ViserServer`.
    token
        Access token the URL path must carry (:func:`new_token`), or None.
    allow_origins
        More origins whose pages may connect (``http://host:port``).
    host
        The address the server listens on (default: the server's own).
    log
        Print each refused handshake (and each connection closed for not reading) on
        stderr.
    max_connections
        WebSocket connections open at once; more are refused.
    teacher_token
        A second token, for the teacher's page of ``serve --classroom`` (needs
        ``token``).

    Returns
    -------
    Gate
        Its ``url(host, port)`` is the address to open.
    """
    port = server.get_port()
    extra = {normalise_origin(o) for o in allow_origins}
    if max_connections < 1:
        raise InputError(f"--max-connections must be positive, got {max_connections}")
    if teacher_token is not None and (token is None or teacher_token == token):
        raise InputError("the teacher's token needs a student token of its own")
    gate = Gate(token=token, origins=own_origins(host or server.get_host(), port) | extra, log=log,
                max_connections=max_connections, count=lambda: hooks.open_connections(server),
                teacher_token=teacher_token)
    hooks.set_process_request(server, gate.wrap, admitted=gate.admitted)
    hooks.watch_connections(server, gate.backlog_check)
    return gate


def open_server(
    host: str,
    port: int,
    *,
    token: str | None,
    allow_origins: Iterable[str] = (),
    log: bool = True,
    max_connections: int = DEFAULT_MAX_CONNECTIONS,
    teacher_token: str | None = None,
) -> tuple[viser.ViserServer, Gate]:
    """Start a viser server with the gate in front of it (what ``serve`` does)."""
    extra = [normalise_origin(o) for o in allow_origins]  # bad values: before listening
    if max_connections < 1:
        raise InputError(f"--max-connections must be positive, got {max_connections}")
    server = viser.ViserServer(host=host, port=port, verbose=False)
    try:
        gate = guard(server, token=token, allow_origins=extra, host=host, log=log,
                     max_connections=max_connections, teacher_token=teacher_token)
    except BaseException:
        server.stop()
        raise
    return server, gate
