"""rough_viewer: surface roughness of scanned rock faces.

The compute core lives in :mod:`rough_viewer.core` (numpy, scipy, PyWavelets and
laspy only); the browser app in :mod:`rough_viewer.app`; the command line in
:mod:`rough_viewer.cli`.
"""

__version__ = "0.1.0"
