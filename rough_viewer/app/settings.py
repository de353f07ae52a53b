"""The map's settings as data: what the user chose that changes the picture
(:class:`MapSettings`) and the checks the core needs of them. No viser here."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from rough_viewer.visual import colormaps
from rough_viewer.vocabulary import (
    COLOUR_LAYERS,
    MAP_TITLES,
    MAPS,
    AxisChoice,
    ColourLayerName,
    InputError,
    MapName,
)

DisplayMode = Literal["continuous", "binary"]

#: Maps in the order the GUI lists them; names shown to the user.
MODEL_LABELS: dict[MapName, str] = {name: MAP_TITLES[name] for name in MAPS}

#: Smallest cell size the app accepts (metres): 0.1 mm, for lab scans of joints (a
#: 20 mm joint scanned densely has presets below 1 mm); the grid code checks memory.
MIN_CELL_SIZE = 1e-4

#: Largest cell size the app accepts (metres).
MAX_CELL_SIZE = 10_000.0


@dataclass(frozen=True)
class MapSettings:
    """Everything the user chose that changes the picture (one immutable snapshot)."""

    cell_size: float = 0.25
    """Grid cell edge in metres."""
    model: MapName = "odr"
    """Which roughness map colours the points."""
    axis: AxisChoice = "auto"
    """Dependent axis for OLS and hybrid; ``auto`` = closest to the whole-cloud normal."""
    min_points: int = 4
    """Cells with fewer points get no value."""
    display: DisplayMode = "continuous"
    """Continuous roughness colours, or the binary transform at ``threshold``."""
    threshold: float = 0.05
    """Binary threshold on normalised roughness (0-1)."""
    colormap: str = "viridis"
    """Colour map name (see :mod:`rough_viewer.visual.colormaps`)."""
    stretch: colormaps.Stretch = colormaps.ROUGHNESS_STRETCH
    """How roughness spreads over the colour map (percentiles of the cells or absolute
    limits in metres, linear or log): :class:`rough_viewer.visual.colormaps.Stretch`."""
    layer: ColourLayerName = "roughness"
    """What colours the points: the roughness map, the scan's RGB, its intensity, or
    the distance to the whole-cloud face plane."""
    keep_outliers: bool = False
    """Keep cells whose roughness is larger than the cell (outliers of the hybrid or
    OLS definition, :mod:`rough_viewer.grid.outliers`) in the colour stretch, the
    binary transform, the panels and the zones; by default they are left out and
    drawn in :data:`rough_viewer.visual.colormaps.OUTLIER_RGB`."""

    @property
    def grid_key(self) -> tuple[float, str, int]:
        """Cache key of the grid computation: (cell size, axis, min points)."""
        return (round(float(self.cell_size), 9), self.axis, int(self.min_points))

    def with_(self, **changes: object) -> MapSettings:
        """A copy with some fields changed."""
        return replace(self, **changes)  # type: ignore[arg-type]


def check_settings(settings: MapSettings) -> None:
    """Raise InputError for settings the core cannot use (message for the GUI)."""
    if not np.isfinite(settings.cell_size) or settings.cell_size < MIN_CELL_SIZE:
        raise InputError(
            f"grid size {settings.cell_size:g} m is too small (minimum {MIN_CELL_SIZE:g} m)"
        )
    if settings.min_points < 3:
        raise InputError(f"minimum points per cell must be at least 3, got {settings.min_points}")
    if settings.model not in MODEL_LABELS:
        raise InputError(f"unknown model {settings.model!r}")
    if settings.axis not in ("auto", "x", "y", "z"):
        raise InputError(f"unknown dependent axis {settings.axis!r}")
    if settings.cell_size > MAX_CELL_SIZE:
        raise InputError(f"grid size {settings.cell_size:g} m is too large "
                         f"(maximum {MAX_CELL_SIZE:g} m)")
    if settings.layer not in COLOUR_LAYERS:
        raise InputError(f"unknown colour layer {settings.layer!r}")
    if not isinstance(settings.stretch, colormaps.Stretch):
        raise InputError("the colour stretch must be a Stretch")
    colormaps.lut(settings.colormap)

