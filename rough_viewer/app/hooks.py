"""Where the app reaches into viser 1.1 (pinned ``viser==1.1.*``), in one module.

viser has no public hook for three things a web server must do, so this module
uses its internals, and nothing else in the app does:

- **The WebSocket handshake** (:func:`set_process_request`): viser serves its
  client page and the WebSocket with ``websockets.asyncio.server.serve(...,
  process_request=<its file server>)``. The ``websockets`` ``Server`` object reads
  ``server.process_request`` for every new connection, so wrapping that attribute
  puts a check in front of every HTTP request and handshake. The object is found
  among live objects by its event loop (``ViserServer._websock_server.
  _background_event_loop``), and connections accepted before the wrapper was in
  place are closed.
- **Messages from clients** (:func:`replace_handlers`): viser's
  ``WebsockServer.register_handler`` / ``unregister_handler`` (public methods of
  the private ``ViserServer._websock_server``) let the app put a filter before
  viser's own handler of a message type, or drop a type altogether.
- **One tab's own messages** (:func:`replace_client_handlers`,
  :func:`connection_of`): a tab's client-scoped GUI and scene take its messages
  on its connection (``ClientHandle._websock_connection``), so the same filters
  go there for a tab of ``serve --classroom``; the tab's WebSocket connection
  (``WebsockServer._live_connections``) tells which token it came with.
- **Sending a raw message** (:func:`broadcast`): to put a control's value back in
  the one browser that sent a bad one, and to acknowledge upload parts.
- **Watching connections** (:func:`watch_connections`, :func:`open_connections`):
  viser sends each browser its messages with ``await websocket.send``; a browser
  that stops reading leaves its whole frame (80 MiB on the demo) in the
  connection's write buffer for good. A timer on viser's event loop reads each
  connection's unsent bytes (``transport.get_write_buffer_size()``) and closes
  the ones a check condemns; the handshake hook counts the open connections.

Each of these is exercised by the tests (tests/app/test_gate.py, test_controls.py,
test_uploads.py), so a viser release that moves them fails there first.
"""

from __future__ import annotations

import asyncio
import gc
import weakref
from collections.abc import Callable, Coroutine
from typing import Any, TypeVar, cast

import viser
import viser.infra
from viser import _messages
from websockets.asyncio.server import Server, ServerConnection
from websockets.http11 import Request, Response

M = TypeVar("M", bound=_messages.Message)
Handler = Callable[[int, M], "None | Coroutine[Any, Any, None]"]
ProcessRequest = Callable[[ServerConnection, Request], Any]


def _websock(server: viser.ViserServer) -> viser.infra.WebsockServer:
    return server._websock_server


def event_loop(server: viser.ViserServer) -> asyncio.AbstractEventLoop:
    """The asyncio loop viser's server thread runs."""
    loop = _websock(server)._background_event_loop
    if loop is None:
        raise RuntimeError("viser server is not running")
    return loop


_WS_SERVERS: weakref.WeakKeyDictionary[viser.ViserServer, Server] = weakref.WeakKeyDictionary()


def _ws_server(server: viser.ViserServer) -> Server:
    found = _WS_SERVERS.get(server)
    if found is not None:
        return found
    loop = event_loop(server)
    candidates = [o for o in gc.get_objects() if isinstance(o, Server) and o.loop is loop]
    if len(candidates) != 1:
        raise RuntimeError(f"cannot find viser's WebSocket server ({len(candidates)} candidates)")
    _WS_SERVERS[server] = candidates[0]
    return candidates[0]


def open_connections(server: viser.ViserServer) -> int:
    """WebSocket connections open now (call on viser's event loop: the handshake hook)."""
    return len(_ws_server(server).connections)


def watch_connections(
    server: viser.ViserServer,
    check: Callable[[ServerConnection, int], str | None],
    *,
    interval: float = 1.0,
) -> None:
    """Every ``interval`` seconds, on viser's event loop, call ``check(connection,
    unsent_bytes)`` for each connection (``unsent_bytes``: what its write buffer holds,
    not yet taken by the client); a connection for which it returns a reason is
    closed at once. Stops when the server stops serving."""
    ws = _ws_server(server)
    loop = event_loop(server)

    def tick() -> None:
        if not ws.is_serving():
            return
        for connection in list(ws.handlers):
            transport = connection.transport
            if transport is None or transport.is_closing():
                continue
            try:
                unsent = int(transport.get_write_buffer_size())
            except (AttributeError, RuntimeError, OSError):  # pragma: no cover
                continue
            if check(connection, unsent) is not None:
                transport.abort()
        loop.call_later(interval, tick)

    loop.call_soon_threadsafe(tick)


def set_process_request(
    server: viser.ViserServer,
    wrap: Callable[[ProcessRequest | None], ProcessRequest],
    *,
    admitted: Callable[[ServerConnection], bool],
    timeout: float = 10.0,
) -> None:
    """Replace the HTTP/handshake hook of viser's server by ``wrap(original)``.

    Runs on viser's event loop, so no connection can start between the swap and
    the sweep that follows it: every open connection for which ``admitted`` is
    False (it started before the swap) is closed.

    Raises RuntimeError if viser's server cannot be found (then nothing changed).
    """
    ws = _ws_server(server)

    async def install() -> None:
        ws.process_request = wrap(ws.process_request)
        for connection in list(ws.handlers):
            if not admitted(connection):
                connection.transport.abort()

    asyncio.run_coroutine_threadsafe(install(), event_loop(server)).result(timeout)


def replace_handlers(
    server: viser.ViserServer,
    message_cls: type[M],
    make: Callable[[list[Handler[M]]], Handler[M] | None],
) -> None:
    """Put ``make(viser's handlers)`` in place of viser's handlers of ``message_cls``
    (None: drop messages of that type)."""
    _replace_on(_websock(server), message_cls, make)


def replace_client_handlers(
    client: viser.ClientHandle,
    message_cls: type[M],
    make: Callable[[list[Handler[M]]], Handler[M] | None],
) -> None:
    """:func:`replace_handlers` for the handlers of one tab's own GUI and scene
    (viser's client-scoped ``client.gui`` and ``client.scene`` take that tab's
    messages on its connection, beside the server's handlers)."""
    _replace_on(client._websock_connection, message_cls, make)


def _replace_on(target: viser.infra.WebsockMessageHandler, message_cls: type[M],
                make: Callable[[list[Handler[M]]], Handler[M] | None]) -> None:
    """``make(handlers)`` in place of ``target``'s handlers of ``message_cls``."""
    existing = cast(list[Handler[M]], list(target._incoming_handlers.get(message_cls, [])))
    if existing:
        target.unregister_handler(message_cls)
    new = make(existing)
    if new is not None:
        target.register_handler(message_cls, new)


def connection_of(server: viser.ViserServer, client_id: int) -> ServerConnection | None:
    """The WebSocket connection of a connected tab (None once it has left)."""
    live = getattr(_websock(server), "_live_connections", {})
    found = live.get(client_id)
    return found if isinstance(found, ServerConnection) else None


def broadcast(server: viser.ViserServer, message: _messages.Message) -> None:
    """Send ``message`` to every connected browser (and later ones)."""
    _websock(server).queue_message(message)


def send_to(server: viser.ViserServer, client_id: int, message: _messages.Message) -> None:
    """Send ``message`` to one browser only (nothing if it has left). Unlike
    :func:`broadcast`, viser keeps nothing for browsers that connect later: a
    message per upload part must not pile up in the server for good."""
    client = server.get_clients().get(client_id)
    if client is not None:
        client._websock_connection.queue_message(message)


def uuid_of(handle: Any) -> str:
    """The id viser gives a GUI handle (and the browser's element id)."""
    return str(handle._impl.uuid)


def input_handles(server: viser.ViserServer) -> dict[str, Any]:
    """Every GUI input handle of the server's GUI, by uuid (tests, checks)."""
    return gui_input_handles(server.gui)


def gui_input_handles(gui: viser.GuiApi) -> dict[str, Any]:
    """Every input handle of one GUI (the server's or a tab's own), by uuid."""
    return dict(gui._gui_input_handle_from_uuid)


def http_response(status: int, reason: str, body: bytes, content_type: str) -> Response:
    """A complete HTTP response for the handshake hook."""
    from websockets.datastructures import Headers

    headers = Headers({"Content-Type": content_type, "Content-Length": str(len(body)),
                       "Cache-Control": "no-store"})
    return Response(status, reason, headers, body)
