"""Where an app is shown: the whole server (every tab the same analysis) or one tab.

An app (its shell, scene, controls and uploads) is built on a :class:`Stage`:

- :class:`ServerStage`: the viser server's own GUI and scene, which every browser
  tab shares (``rough-viewer serve``: one analysis for all its tabs);
- :class:`TabStage`: one browser tab's GUI and scene (viser's client-scoped
  ``client.gui`` and ``client.scene``), which no other tab sees
  (``serve --classroom``: every tab its own analysis,
  :mod:`rough_viewer.app.classroom`).

Both offer the same few things: the GUI, the scene, the tabs they show to, the
camera a tab opens with, connect and disconnect events, and where the messages of
their tabs arrive (so that the app's checks of browsers' values sit in front of
viser's handlers of exactly these tabs).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any, Protocol, TypeVar

import viser
from viser import _messages

from rough_viewer.app import hooks

M = TypeVar("M", bound=_messages.Message)
Listener = Callable[[viser.ClientHandle], None]


class Stage(Protocol):
    """What an app is shown on (see the module docstring)."""

    @property
    def server(self) -> viser.ViserServer:
        """The viser server (shared by every stage of a process)."""
        ...

    @property
    def gui(self) -> viser.GuiApi:
        """The GUI the app's controls are added to."""
        ...

    @property
    def scene(self) -> viser.SceneApi:
        """The scene the app's nodes are added to."""
        ...

    @property
    def initial_camera(self) -> Any:
        """The camera a browser opens with (written by the scene)."""
        ...

    def clients(self) -> dict[int, viser.ClientHandle]:
        """The connected tabs this stage shows to."""
        ...

    def on_client_connect(self, listener: Listener) -> None:
        """Call ``listener(client)`` for each tab this stage shows to, as it connects."""
        ...

    def on_client_disconnect(self, listener: Listener) -> None:
        """Call ``listener(client)`` when one of this stage's tabs leaves."""
        ...

    def replace_handlers(self, message_cls: type[M],
                         make: Callable[[list[hooks.Handler[M]]], hooks.Handler[M] | None]
                         ) -> None:
        """Put ``make(viser's handlers)`` in front of viser's handlers of
        ``message_cls`` for this stage's tabs (None: drop those messages)."""
        ...

    def input_handles(self) -> dict[str, Any]:
        """The GUI input handles of this stage's GUI, by uuid."""
        ...

    def send(self, client_id: int, message: _messages.Message) -> None:
        """Send ``message`` to one tab of this stage."""
        ...


def stage_of(target: viser.ViserServer | Stage) -> Stage:
    """``target`` as a stage (a viser server: its own, shared GUI and scene)."""
    return ServerStage(target) if isinstance(target, viser.ViserServer) else target


class ServerStage:
    """The viser server's own GUI and scene, shared by every tab."""

    def __init__(self, server: viser.ViserServer) -> None:
        self._server = server

    @property
    def server(self) -> viser.ViserServer:
        return self._server

    @property
    def gui(self) -> viser.GuiApi:
        return self._server.gui

    @property
    def scene(self) -> viser.SceneApi:
        return self._server.scene

    @property
    def initial_camera(self) -> Any:
        return self._server.initial_camera

    def clients(self) -> dict[int, viser.ClientHandle]:
        return dict(self._server.get_clients())

    def on_client_connect(self, listener: Listener) -> None:
        self._server.on_client_connect(listener)

    def on_client_disconnect(self, listener: Listener) -> None:
        self._server.on_client_disconnect(listener)

    def replace_handlers(self, message_cls: type[M],
                         make: Callable[[list[hooks.Handler[M]]], hooks.Handler[M] | None]
                         ) -> None:
        hooks.replace_handlers(self._server, message_cls, make)

    def input_handles(self) -> dict[str, Any]:
        return hooks.input_handles(self._server)

    def send(self, client_id: int, message: _messages.Message) -> None:
        """To every tab, since they all show this GUI (a value put back must be put
        back everywhere, and kept for later tabs)."""
        hooks.broadcast(self._server, message)


class TabStage:
    """One browser tab's own GUI and scene (viser's client-scoped API).

    The tab is connected when the stage is made; :meth:`start` calls the connect
    listeners (once the app on this stage is built, as viser would for a tab that
    connects to a built app), and the disconnect listeners are called when the tab
    leaves.
    """

    def __init__(self, server: viser.ViserServer, client: viser.ClientHandle) -> None:
        self._server = server
        self.client = client
        self._camera = SimpleNamespace(position=None, look_at=None, up=None, fov=None,
                                       near=None, far=None)
        self._connect: list[Listener] = []
        self._disconnect: list[Listener] = []
        self._started = False
        self._left = False
        self._lock = threading.Lock()

    @property
    def server(self) -> viser.ViserServer:
        return self._server

    @property
    def client_id(self) -> int:
        return int(self.client.client_id)

    @property
    def gui(self) -> viser.GuiApi:
        return self.client.gui

    @property
    def scene(self) -> viser.SceneApi:
        return self.client.scene

    @property
    def initial_camera(self) -> Any:
        """A record of the camera the scene would give new tabs: a tab's stage has
        no new tabs (its own camera is placed directly)."""
        return self._camera

    @property
    def connected(self) -> bool:
        return not self._left and self.client_id in self._server.get_clients()

    def clients(self) -> dict[int, viser.ClientHandle]:
        return {self.client_id: self.client} if self.connected else {}

    def on_client_connect(self, listener: Listener) -> None:
        with self._lock:
            self._connect.append(listener)
            started = self._started
        if started and self.connected:
            listener(self.client)

    def on_client_disconnect(self, listener: Listener) -> None:
        with self._lock:
            self._disconnect.append(listener)

    def start(self) -> None:
        """The app on this stage is built: tell its connect listeners about the tab."""
        with self._lock:
            self._started = True
            listeners = list(self._connect)
        for listener in listeners:
            listener(self.client)

    def left(self) -> None:
        """The tab has gone: tell the disconnect listeners (once)."""
        with self._lock:
            if self._left:
                return
            self._left = True
            listeners = list(self._disconnect)
        for listener in listeners:
            listener(self.client)

    def replace_handlers(self, message_cls: type[M],
                         make: Callable[[list[hooks.Handler[M]]], hooks.Handler[M] | None]
                         ) -> None:
        hooks.replace_client_handlers(self.client, message_cls, make)

    def input_handles(self) -> dict[str, Any]:
        return hooks.gui_input_handles(self.client.gui)

    def send(self, client_id: int, message: _messages.Message) -> None:
        if client_id == self.client_id:
            hooks.send_to(self._server, client_id, message)
