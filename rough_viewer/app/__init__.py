"""The browser app (viser): pure state in :mod:`.state`, picking in :mod:`.picking`,
display sampling in :mod:`.sampling`, the worker in :mod:`.controller`, the GUI in
:mod:`.layout` and the assembly in :mod:`.server` (``build_app``)."""
