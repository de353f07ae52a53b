"""The app's features: each tab (or folder) is one module with ``mount(host)``.

A feature is given a :class:`rough_viewer.app.host.Host` and nothing else of the
app. Its controls live in its tab, its work is jobs, and it follows the map through
the host's events. A feature that has a part in saved views implements
:class:`~rough_viewer.app.host.SavedViewPart` (``snapshot()``, ``restore(view)``);
one whose panels can be exported implements :class:`~rough_viewer.app.host.
FigureSource` (``figures()``). Saved views (:mod:`rough_viewer.app.views`) and the
Export folder compose those and know no feature's fields, so a new feature is one
module here and one line in :data:`rough_viewer.app.server.FEATURES`.

The map (:mod:`.map`) comes first: the others may use its API (its settings, its
requests, showing a cloud).
"""
