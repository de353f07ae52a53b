"""Directional roughness of triangulated surfaces (TIN): Grasselli's
``theta*max/(C+1)`` (Grasselli 2001; Tatone and Grasselli 2009) and ``Delta-T``
(Babanouri and Karami Nasab 2017), for the whole surface and as maps of circular
windows.

Modules: :mod:`.surface` (a cloud triangulated in its best-fit plane; the facets of
a mesh), :mod:`.directional` (apparent dips, the two parameters, window maps).
"""

from rough_viewer.tin.directional import (
    DirectionalRoughness,
    WindowRoughness,
    apparent_dips,
    azimuths,
    directional_roughness,
    window_roughness,
)
from rough_viewer.tin.surface import Facets, facets, triangulate_cloud

__all__ = [
    "DirectionalRoughness",
    "Facets",
    "WindowRoughness",
    "apparent_dips",
    "azimuths",
    "directional_roughness",
    "facets",
    "triangulate_cloud",
    "window_roughness",
]
