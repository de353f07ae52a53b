"""The browser app (viser), by role.

Plain data, no viser:
:mod:`.state` (settings, the loaded cloud and its byte-bounded grid cache,
colours), :mod:`.picking` (click ray -> point), :mod:`.sampling` (which points to
draw), :mod:`.panels` (panel figures), :mod:`.markup` (escaping for Markdown, safe
error messages), :mod:`.files` (the data folder, reading within memory).

On the server:
:mod:`.scene` (cloud, camera, axis, pick markers), :mod:`.layout` (the map's
controls), :mod:`.worker` (the one worker thread and the :class:`~.worker.Job`
type), :mod:`.jobs` (the map's jobs: load, view, panels, pick), :mod:`.server`
(wiring: :func:`~.server.build_app`, :class:`~.server.App`, :data:`~.server.MODES`).

Safety (every browser message is hostile): :mod:`.gate` (Origin check and access
token on the WebSocket), :mod:`.controls` (client values checked against each
control's options and range), :mod:`.uploads` (uploads streamed to disk with a
limit), :mod:`.hooks` (the only module that touches viser's internals).

Modes: :mod:`.profile_mode` (Profile tab), :mod:`.board_mode` (Board tab),
:mod:`.bias_panel` (Bias tab), :mod:`.zones_mode` (Zones tab), :mod:`.export_mode`
(the Export folder: downloads sent to the browser, saved views). Saved views
(``serve --view``): :mod:`.views` (what the app shows as a
:class:`rough_viewer.report.view.View`, and back).

Adding a mode (a "Zones" tab, an "Export" folder, ...) is one new module and one
line of wiring:

1. Write ``rough_viewer/app/zones_mode.py`` with ``mount(app) -> ZonesMode``. It
   creates its controls inside ``with app.gui.tabs.add_tab("Zones"):`` (or
   ``with app.server.gui.add_folder("Export"):``), registers them with
   ``app.controls.allow(...)`` (or ``app.controls.rule(handle, check)`` for an extra
   check; unregistered controls cannot be set from a browser), and returns a small
   dataclass with its handles and state.
2. Its work is one or more :class:`~.worker.Job` subclasses (frozen dataclasses with
   a ``lane`` and a ``stages(app, run)`` generator yielding after each stage); its
   callbacks only ``app.submit(SomeJob(...))``. Jobs read ``app.shown`` (the loaded
   cloud, the settings and grid result on screen), show problems with
   ``app.show_error``, escape any user or file text with :func:`.markup.md`, and may
   add a click handler to ``app.click_handlers`` (``handler(app, pick) -> bool``).
   A mode that follows the map (grid, model, threshold, file) adds
   ``listener(app)`` to ``app.view_listeners``: it is called on the worker after
   every view's colours are shown, and should only submit its own job. A mode
   that must know when another cloud is put in the scene (a file loaded, the board
   opened or put back) adds ``handler(app)`` to ``app.cloud_handlers``.
   Uploads go through ``app.uploads.register(handle, on_file)``.
3. Add ``zones_mode.mount`` to :data:`.server.MODES`. Tests reach the mode with
   ``app.mode(ZonesMode)``.
"""
