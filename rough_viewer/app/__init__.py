"""The browser app (viser), in layers that run one way (``tests/test_layout.py``).

Core (plain data and the two writers, no host): :mod:`.state` (map settings, the
loaded cloud and its byte-bounded grid cache, colours), :mod:`.session` (what is
shown, what is put aside, the panels' keys, the last pick; written on the worker
only), :mod:`.worker` (the one worker thread and the :class:`~.worker.Job` type),
:mod:`.scene` (the only writer of viser's scene), :mod:`.files` (the data folder,
reading within memory), :mod:`.picking`, :mod:`.sampling`, :mod:`.markup`,
:mod:`.limits`.

Host: :mod:`.host`, the :class:`~.host.Host` protocol every feature is given (its
tab, the scene, the session, submitting jobs, events, messages, other features).

UI: :mod:`.shell` (the host), :mod:`.binding` (one binding per tab between its
controls and its settings; the only place that sets controls quietly), and the
server's safety (every browser message is hostile): :mod:`.gate` (Origin check and
access token), :mod:`.controls` (client values checked against each control),
:mod:`.uploads` (uploads streamed to disk with a limit), :mod:`.hooks` (the only
module that touches viser's internals); :mod:`.layout` (what the tabs' widgets
share).

Features (:mod:`.features`): the Map, Panels, File, Profile, Board, Bias and Zones
tabs and the Export folder, each one module with ``mount(host)``; :mod:`.views`
(saved views, composed from the features' parts).

Build: :mod:`.server` (:func:`~.server.build_app`, :class:`~.server.App`,
:data:`~.server.FEATURES`).

Adding a feature (a "Sets" tab, say) is one module and one line:

1. Write ``rough_viewer/app/features/sets.py`` with ``mount(host) -> SetsFeature``. It
   creates its controls inside ``with host.tab("Sets"):``, registers them with
   ``host.allow(...)`` (or ``host.rule(handle, check)`` for an extra check;
   unregistered controls cannot be set from a browser), wires them with a
   :class:`~.binding.Binding` whose callbacks only ``host.submit(SomeJob(...))``, and
   returns a small dataclass with its handles and state.
2. Its work is :class:`~.worker.Job` subclasses (frozen dataclasses with a ``lane``
   and a ``stages(host, run)`` generator yielding after each stage). Jobs read
   ``host.session.shown`` (the loaded cloud, the settings and grid result on
   screen), draw with ``host.scene``, show problems with ``host.show_error``
   (raise :class:`rough_viewer.vocabulary.InputError` for a user's error; anything
   else is logged as an internal error), and escape any user or file text with
   :func:`.markup.md`. A feature that follows the map subscribes with
   ``host.on_render(listener)`` (called on the worker after every map; submit a job
   there), a new cloud with ``host.on_cloud``, clicks with ``host.on_click``.
3. For saved views, implement ``snapshot()`` and ``restore(view)``; for the Export
   folder's figures, ``figures()`` (:class:`~.host.SavedViewPart`,
   :class:`~.host.FigureSource`).
4. Add ``sets.mount`` to :data:`.server.FEATURES`. Tests reach the feature with
   ``app.feature(SetsFeature)``.
"""
