"""Every value a browser sends is checked before the app sees it.

viser applies a client's ``GuiUpdateMessage`` to the control and runs its
callbacks. A page that speaks the protocol can send any value (a dropdown entry
that is not an option, "abc" or NaN for a number, a reversed range) and any
property (a control's options, limits or label, for every tab). :class:`ClientValues`
sits in front of viser's handler (:func:`rough_viewer.app.hooks.replace_handlers`):

- only ``value`` may change; other properties from a client are ignored;
- the value is checked against the control's own options and range
  (:func:`check_value`: type, finiteness, min/max, integer steps, dropdown
  options, text length, a pressed button is ``True``) and any extra rule the app
  registered (:meth:`ClientValues.rule`);
- a bad value never reaches the control: the control is put back to its last
  good value in the sender's browser, with a notice saying why;
- messages for controls the app did not create, disabled buttons, and viser's
  share-link requests are dropped.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import viser
from viser import _messages

from rough_viewer.app import hooks
from rough_viewer.app.limits import MAX_REFUSALS, MAX_TEXT
from rough_viewer.app.stage import Stage, stage_of
from rough_viewer.vocabulary import InputError

Rule = Callable[[Any], Any]
"""Extra check of a value: returns the value to use or raises InputError."""


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{what} must be a number")
    v = float(value)
    if not math.isfinite(v):
        raise InputError(f"{what} must be a finite number")
    return v


def _in_range(v: float, lo: float | None, hi: float | None, what: str) -> None:
    if lo is not None and v < lo - 1e-12 * max(1.0, abs(lo)):
        raise InputError(f"{what} must be at least {lo:g}")
    if hi is not None and v > hi + 1e-12 * max(1.0, abs(hi)):
        raise InputError(f"{what} must be at most {hi:g}")


def check_value(handle: Any, value: Any) -> Any:
    """``value`` checked against ``handle``'s kind, options and range; returns the
    value to apply (numbers as the control's type). Raises InputError."""
    label = getattr(handle, "label", "value")
    what = f"'{label}'"
    if isinstance(handle, viser.GuiButtonHandle):
        if value is not True:
            raise InputError(f"{what}: a button press must be true")
        return True
    if isinstance(handle, (viser.GuiDropdownHandle, viser.GuiButtonGroupHandle)):
        if not isinstance(value, str) or value not in handle.options:
            raise InputError(f"{what} must be one of its options")
        return value
    if isinstance(handle, viser.GuiCheckboxHandle):
        if not isinstance(value, bool):
            raise InputError(f"{what} must be true or false")
        return value
    if isinstance(handle, viser.GuiTextHandle):
        if not isinstance(value, str) or len(value) > MAX_TEXT or "\x00" in value:
            raise InputError(f"{what} must be text of at most {MAX_TEXT} characters")
        return value
    if isinstance(handle, viser.GuiMultiSliderHandle):
        return _check_multi_slider(handle, value, what)
    if isinstance(handle, (viser.GuiNumberHandle, viser.GuiSliderHandle)):
        return _check_number(handle, value, what)
    raise InputError(f"{what} cannot be set from the browser")


def _check_multi_slider(handle: Any, value: Any, what: str) -> tuple[Any, ...]:
    """A multi-slider's ends: as many numbers as it has, in range, increasing at least
    its minimum range apart (each as the control's type)."""
    current = handle.value
    if not isinstance(value, (list, tuple)) or len(value) != len(current):
        raise InputError(f"{what} must be {len(current)} numbers")
    vs = [_number(v, what) for v in value]
    for v in vs:
        _in_range(v, handle.min, handle.max, what)
    gap = handle.min_range or 0.0
    if any(b - a < gap - 1e-12 for a, b in zip(vs, vs[1:], strict=False)):
        raise InputError(f"{what} must be increasing, at least {gap:g} apart")
    return tuple(type(c)(v) for c, v in zip(current, vs, strict=True))


def _check_number(handle: Any, value: Any, what: str) -> float | int:
    """A number field's or slider's value: in range, whole for a whole-number control."""
    v = _number(value, what)
    _in_range(v, handle.min, handle.max, what)
    if isinstance(handle.value, int):
        if not v.is_integer():
            raise InputError(f"{what} must be a whole number")
        return int(v)
    return v


@dataclass(frozen=True)
class Rejected:
    """A client value that was refused (kept for the tests and diagnostics)."""

    label: str
    reason: str


class ClientValues:
    """The filter in front of viser's GUI updates (see the module docstring).

    Parameters
    ----------
    server
        The viser server whose clients are checked (its own GUI), or a stage (one
        tab's GUI: :mod:`rough_viewer.app.stage`).
    notify
        ``notify(client_id, title, message)``: tell one browser why its value
        was put back.
    """

    def __init__(self, server: viser.ViserServer | Stage,
                 notify: Callable[[int, str, str], None]) -> None:
        self._stage = stage = stage_of(server)
        self._notify = notify
        self._rules: dict[str, list[Rule]] = {}
        self._lock = threading.Lock()
        self.rejected: deque[Rejected] = deque(maxlen=MAX_REFUSALS)
        """The last refused values, oldest first."""
        stage.replace_handlers(_messages.GuiUpdateMessage, self._make_filter)
        self.dropped_clicks = 0
        """Malformed scene clicks dropped (:func:`pointer_message_ok`)."""
        stage.replace_handlers(_messages.ScenePointerMessage, self._pointer_filter)
        # a connected page must not open a public tunnel to this server
        hooks.replace_handlers(stage.server, _messages.ShareUrlRequest, lambda _old: None)
        hooks.replace_handlers(stage.server, _messages.ShareUrlDisconnect, lambda _old: None)

    def _pointer_filter(self, viser_handlers: list[hooks.Handler[_messages.ScenePointerMessage]]
                        ) -> hooks.Handler[_messages.ScenePointerMessage]:
        async def scene_pointer(client_id: int, message: _messages.ScenePointerMessage) -> None:
            if not pointer_message_ok(message):
                self.dropped_clicks += 1  # a browser never sends it
                return
            await _pass_on(viser_handlers, client_id, message)

        return scene_pointer

    def rule(self, handle: Any, check: Rule) -> None:
        """Add ``check`` to the checks of values a client sends to ``handle``."""
        with self._lock:
            self._rules.setdefault(hooks.uuid_of(handle), []).append(check)

    def allow(self, *handles: Any) -> None:
        """Let clients set these controls (checked by :func:`check_value` only)."""
        with self._lock:
            for h in handles:
                self._rules.setdefault(hooks.uuid_of(h), [])

    def allowed(self, handle: Any) -> bool:
        with self._lock:
            return hooks.uuid_of(handle) in self._rules

    def _make_filter(self, viser_handlers: list[hooks.Handler[_messages.GuiUpdateMessage]]
                     ) -> hooks.Handler[_messages.GuiUpdateMessage]:
        async def gui_update(client_id: int, message: _messages.GuiUpdateMessage) -> None:
            checked = self.check(client_id, message)
            if checked is not None:
                await _pass_on(viser_handlers, client_id, checked)

        return gui_update

    def check(self, client_id: int, message: _messages.GuiUpdateMessage
              ) -> _messages.GuiUpdateMessage | None:
        """The message to pass on to viser, or None to drop it (see the module docstring)."""
        handle = self._stage.input_handles().get(message.uuid)
        with self._lock:
            rules = self._rules.get(message.uuid)
        updates = message.updates if isinstance(message.updates, dict) else {}
        if handle is None or rules is None or "value" not in updates:
            return None
        if isinstance(handle, viser.GuiButtonHandle) and handle.disabled:
            return None
        try:
            value = check_value(handle, updates["value"])
            for rule in rules:
                value = rule(value)
        except InputError as exc:
            self._put_back(client_id, handle, str(exc))
            return None
        return _messages.GuiUpdateMessage(message.uuid, {"value": value})

    def _put_back(self, client_id: int, handle: Any, reason: str) -> None:
        self.rejected.append(Rejected(str(handle.label), reason))
        if not isinstance(handle, viser.GuiButtonHandle):
            self._stage.send(client_id, _messages.GuiUpdateMessage(
                hooks.uuid_of(handle), {"value": handle.value}))
        self._notify(client_id, "Value not accepted",
                     f"{reason}; the last good value is kept.")


async def _pass_on(handlers: list[Any], client_id: int, message: Any) -> None:
    """Give a checked message to viser's own handlers (sync or async)."""
    for handler in handlers:
        out = handler(client_id, message)
        if out is not None:
            await out


#: Largest coordinate a click ray may carry (the display frame is metres around the
#: cloud's centre; anything larger is not a click on it).
MAX_RAY_COORDINATE = 1e9


def _numbers(value: object, n: int, bound: float) -> bool:
    """``value`` is a list or tuple of ``n`` finite numbers (no bools) within bound."""
    return (isinstance(value, (list, tuple)) and len(value) == n
            and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                    and math.isfinite(v) and abs(v) <= bound for v in value))


def pointer_message_ok(message: _messages.ScenePointerMessage) -> bool:
    """A scene click as a browser sends it: a known event, 3-vector rays (or none)
    and at least one screen position (viser indexes ``screen_pos[0]``). A malformed
    one raised inside viser's handler (IndexError, an overflow warning)."""
    if message.event_type not in ("click", "rect-select"):
        return False
    for ray in (message.ray_origin, message.ray_direction):
        if ray is not None and not _numbers(ray, 3, MAX_RAY_COORDINATE):
            return False
    pos = message.screen_pos
    return (isinstance(pos, (list, tuple)) and 1 <= len(pos) <= 2
            and all(_numbers(p, 2, 1e6) for p in pos)
            and (message.modifier is None or isinstance(message.modifier, str)))

