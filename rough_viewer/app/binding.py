"""Between a tab's controls and its settings: one :class:`Binding` per tab.

A tab's binding (a subclass, in the feature's module) is the one place that reads
its controls into settings, shows settings in its controls, and makes the controls
follow a new cloud (options, labels and units). The app shows values in controls
*quietly*: the controls' callbacks queue no work meanwhile, because the values are
the app's answer, not a person's request. This module holds that mechanism, and
nothing else in the app sets controls quietly.

Callbacks registered with :meth:`Binding.on_change` run on viser's thread pool when
a browser (or a test, or the app outside a quiet block) changes a control; they
only submit a job (``tests/test_layout.py`` checks). Every write of a handle goes
through a binding (:meth:`Binding.set`, :meth:`Binding.write`,
:meth:`Binding.show_figure`) or the shell's messages, and each checks that it runs
on a worker (:class:`~rough_viewer.app.worker.NotOnWorker` otherwise).
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterable, Iterator
from typing import Any, TypeVar

from rough_viewer.app.layout import set_figure
from rough_viewer.app.worker import require_a_worker

T = TypeVar("T")

_quiet = threading.local()


def assign(handle: Any, value: T) -> None:
    """Set a GUI handle's value as a person would (its callbacks run at once, on this
    thread). viser 1.1's type hints make ``handle.value`` read-only for mypy although
    viser assigns it at run time; this one function is where the app does."""
    setattr(handle, "value", value)  # noqa: B010 - see the docstring


def asking() -> int | None:
    """The browser (viser client id) whose control change this thread is handling,
    or None outside such a callback: the worker counts its jobs (at most
    ``max_per_owner`` wait for one browser)."""
    return getattr(_quiet, "client", None)


def quiet() -> bool:
    """True while this thread shows values quietly (callbacks queue nothing)."""
    return bool(getattr(_quiet, "on", False))


class Binding:
    """The quiet-setting mechanism and the wiring every tab's binding shares."""

    @contextlib.contextmanager
    def quietly(self) -> Iterator[None]:
        """Set controls inside the block without their callbacks queuing work (nested
        blocks keep it)."""
        before = quiet()
        _quiet.on = True
        try:
            yield
        finally:
            _quiet.on = before

    def set(self, handle: Any, value: object) -> None:
        """Show ``value`` in ``handle`` quietly (nothing when it holds it already;
        on the worker)."""
        require_a_worker("a control's value")
        with self.quietly():
            if handle.value != value:
                assign(handle, value)

    def write(self, handle: Any, **attributes: object) -> None:
        """Set other attributes of ``handle`` than its value (``content``,
        ``label``, ``visible``, ``options``, ...) quietly, on the worker."""
        require_a_worker(f"a control's {', '.join(attributes)}")
        with self.quietly():
            for name, value in attributes.items():
                setattr(handle, name, value)

    def show_figure(self, handle: Any, fig: Any) -> None:
        """Show a plotly figure in ``handle`` at the height its builder laid it out
        for (:func:`rough_viewer.app.layout.set_figure`), on the worker."""
        require_a_worker("a plot")
        set_figure(handle, fig)

    def on_change(self, handles: Iterable[Any], callback: Callable[[Any], object]) -> None:
        """Call ``callback(handle)`` when one of ``handles`` is changed (not quietly)."""
        for handle in handles:
            def changed(event: object, handle: Any = handle) -> None:
                if not quiet():
                    before = asking()
                    client = getattr(event, "client_id", None)
                    _quiet.client = client if isinstance(client, int) else None
                    try:
                        callback(handle)
                    finally:
                        _quiet.client = before

            if hasattr(handle, "on_click"):
                handle.on_click(changed)
            else:
                handle.on_update(changed)
