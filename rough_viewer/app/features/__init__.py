"""The app's features: each tab (or folder) is one module, or one package, with
``mount(host)``.

A feature is given a :class:`rough_viewer.app.host.Host` and nothing else of the
app, and imports no other feature's module (``tests/test_layout.py`` checks): what
it needs of the map (its settings, a map request, the points' colours, showing or
loading a cloud) or of another feature goes through the host. Its controls live
in its tab, its work is jobs, and it follows the map through the host's events. A
feature that has a part in saved views implements
:class:`~rough_viewer.app.host.SavedViewPart` (``snapshot()``, ``restore(view)``);
one whose panels can be exported implements :class:`~rough_viewer.app.host.
FigureSource` (``figures()``). Saved views (:mod:`rough_viewer.app.views`) and the
Export folder compose those and know no feature's fields, so a new feature is one
module here and one line in :data:`rough_viewer.app.server.FEATURES`.

The map (:mod:`.map`) comes first: the shell hands the host's map calls
(:class:`~rough_viewer.app.host.MapService`) to it. Callbacks only submit jobs, and
handles are written only through a :class:`~rough_viewer.app.binding.Binding` or
the host's messages, on the worker.
"""
