"""The map's settings as data: what the user chose that changes the picture
(:class:`MapSettings`) and the checks the core needs of them, and what the Map tab's
controls hold (:class:`MapForm`) with the pure rules that move it (:func:`apply`).
No viser here: every rule is tested without a browser."""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Literal

import numpy as np

from rough_viewer.app.units import Units
from rough_viewer.visual import colormaps
from rough_viewer.vocabulary import (
    AXIS_CHOICES,
    COLOUR_LAYER_LABELS,
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



# ----------------------------------------------------------------------------- the form

#: The Map tab's entries -> the names the settings use.
MODEL_BY_LABEL: dict[str, MapName] = {label: name for name, label in MODEL_LABELS.items()}
DISPLAY_BY_NAME: dict[str, DisplayMode] = {"continuous": "continuous", "binary": "binary"}
AXIS_BY_NAME: dict[str, AxisChoice] = {a: a for a in AXIS_CHOICES}
LAYER_BY_LABEL: dict[str, ColourLayerName] = {COLOUR_LAYER_LABELS[n]: n for n in COLOUR_LAYERS}


def resolve_colormap(choice: str, model: str) -> str:
    """Colour map actually used: ``auto`` -> the map's own
    (:func:`rough_viewer.visual.colormaps.default_colormap`: magma, a sequential map,
    for e_ols; viridis for the roughness maps).

    >>> resolve_colormap("auto", "e_ols"), resolve_colormap("cividis", "odr")
    ('magma', 'cividis')
    """
    if choice == "auto":
        return colormaps.default_colormap(model)
    return choice


def grid_options(presets: tuple[float, ...], units: Units) -> dict[str, float]:
    """Grid dropdown entries (the presets in the cloud's unit, as text) -> metres.

    >>> grid_options((0.5, 0.25), Units("m"))
    {'0.5': 0.5, '0.25': 0.25}
    """
    return {f"{units.length(g):g}": g for g in presets}


def grid_choice(cell_size: float, options: dict[str, float]) -> str:
    """The grid dropdown entry for a cell size (metres): a preset, or ``free``.

    >>> grid_choice(0.25, {"0.5": 0.5, "0.25": 0.25}), grid_choice(0.3, {"0.5": 0.5})
    ('0.25', 'free')
    """
    for text, size in options.items():
        if abs(size - cell_size) <= 1e-9 * max(size, 1e-12):
            return text
    return "free"


def round_limit(value: float) -> float:
    """A colour limit as typed: 3 significant digits (0 and NaN stay 0).

    >>> round_limit(6.2249), round_limit(float("nan"))
    (6.22, 0.0)
    """
    v = float(value)
    return float(f"{v:.3g}") if v == v and v != 0 else 0.0


@dataclass(frozen=True)
class GridChoices:
    """What the Map tab's lengths mean for the shown cloud: its grid dropdown's
    entries and the unit the length fields are typed in."""

    values: dict[str, float]
    """Grid dropdown entry -> cell size, metres (:func:`grid_options`)."""
    units: Units = Units("m")

    @staticmethod
    def of(presets: tuple[float, ...], units: Units) -> GridChoices:
        return GridChoices(grid_options(presets, units), units)


@dataclass(frozen=True)
class MapForm:
    """What the Map tab's controls hold, as data: entries as the dropdowns show them,
    lengths in the cloud's unit and roughness limits in its roughness unit.

    :func:`apply` moves a form by one person's change, with the rules that keep twin
    controls together; :func:`settings_of` reads the :class:`MapSettings` it asks for
    and :func:`form_of` shows settings in a form. The binding of the Map tab only
    copies a form into the controls and back.
    """

    grid: str = "free"
    """A grid dropdown entry (:attr:`GridChoices.values`) or ``free``."""
    grid_free: float = 0.25
    """The free grid size, in the cloud's unit."""
    model: str = MODEL_LABELS["odr"]
    axis: str = "auto"
    display: str = "continuous"
    threshold: float = 0.05
    min_points: int = 4
    colormap: str = "auto"
    """A colour map name, or ``auto`` (:func:`resolve_colormap`)."""
    layer: str = COLOUR_LAYER_LABELS["roughness"]
    keep_outliers: bool = False
    stretch: str = "percentile"
    """``percentile`` or ``absolute``."""
    log: bool = True
    percentiles: tuple[float, float] = (2.0, 98.0)
    pct_lo: float = 2.0
    """The slider's lower end, typed."""
    pct_hi: float = 98.0
    range_lo: float = 0.0
    """The lowest roughness of an absolute stretch, in the roughness unit."""
    range_hi: float = 0.0


#: The fields of :class:`MapForm` a change may name, besides ``toggle``.
FORM_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(MapForm))

Change = tuple[str, object]
"""(a field of :class:`MapForm` or ``toggle``, the value a person gave it)."""


def apply(form: MapForm, change: Change, choices: GridChoices) -> MapForm:
    """The form once a person made ``change``, with the controls that follow it moved.

    A typed free size picks the ``free`` grid; a preset shows its size in the free
    field; typed percentiles move the slider; dragged or typed percentiles pick the
    percentile stretch and typed limits the absolute one; the typed percentile fields
    always show the slider's ends; ``toggle`` flips ODR and OLS (from any other model
    to ODR). Applied one after another, the last change of a group wins.

    >>> c = GridChoices({"0.5": 0.5, "0.25": 0.25})
    >>> f = apply(MapForm(grid="0.5", grid_free=0.5), ("grid_free", 0.3), c)
    >>> f.grid, f.grid_free
    ('free', 0.3)
    >>> apply(f, ("grid", "0.25"), c).grid_free
    0.25
    >>> f = apply(MapForm(), ("pct_hi", 1.0), c)
    >>> f.percentiles, f.pct_lo, f.pct_hi, f.stretch
    ((1.0, 2.0), 1.0, 2.0, 'percentile')
    >>> apply(MapForm(), ("range_hi", 4.0), c).stretch
    'absolute'
    >>> apply(MapForm(), ("toggle", True), c).model
    'OLS'
    """
    name, value = change
    if name == "toggle":
        flipped = MODEL_LABELS["ols"] if form.model == MODEL_LABELS["odr"] else MODEL_LABELS["odr"]
        return replace(form, model=flipped)
    if name not in FORM_FIELDS:
        raise ValueError(f"the Map tab has no control {name!r}")
    form = replace(form, **{name: value})  # type: ignore[arg-type]
    if name == "grid_free":
        form = replace(form, grid="free")
    elif name == "grid":
        size = choices.values.get(form.grid)
        if size is not None:
            form = replace(form, grid_free=choices.units.length(size))
    elif name in ("pct_lo", "pct_hi"):
        lo, hi = sorted((float(form.pct_lo), float(form.pct_hi)))
        form = replace(form, percentiles=(lo, hi), stretch="percentile")
    elif name == "percentiles":
        form = replace(form, stretch="percentile")
    elif name in ("range_lo", "range_hi"):
        form = replace(form, stretch="absolute")
    return slider_ends(form)


def slider_ends(form: MapForm) -> MapForm:
    """The typed percentile fields showing the slider's two ends."""
    lo, hi = (float(v) for v in form.percentiles)
    return replace(form, pct_lo=lo, pct_hi=hi)


def settle(form: MapForm, changes: tuple[Change, ...], choices: GridChoices) -> MapForm:
    """``form`` once ``changes`` (oldest first) are made, one after another."""
    for change in changes:
        form = apply(form, change, choices)
    return slider_ends(form)


def settings_of(form: MapForm, choices: GridChoices) -> MapSettings:
    """The settings ``form`` asks for (lengths typed in the cloud's unit become
    metres). InputError when a field holds a value the app cannot use.

    >>> s = settings_of(MapForm(grid="0.5"), GridChoices({"0.5": 0.5}))
    >>> s.cell_size, s.model, s.colormap
    (0.5, 'odr', 'viridis')
    """
    u = choices.units
    if form.grid == "free":
        cell = float(form.grid_free) * u.per
    else:
        preset = choices.values.get(form.grid)
        if preset is None:
            raise InputError("the grid size is not one of this cloud's presets")
        cell = preset
    model = MODEL_BY_LABEL.get(form.model)
    axis = AXIS_BY_NAME.get(form.axis)
    display = DISPLAY_BY_NAME.get(form.display)
    layer = LAYER_BY_LABEL.get(form.layer)
    if model is None or axis is None or display is None or layer is None:
        raise InputError("a control holds a value that is not one of its options")
    return MapSettings(cell_size=cell, model=model, axis=axis,
                       min_points=int(form.min_points), display=display,
                       threshold=float(form.threshold),
                       colormap=resolve_colormap(form.colormap, model),
                       stretch=stretch_of(form, u), layer=layer,
                       keep_outliers=bool(form.keep_outliers))


def stretch_of(form: MapForm, units: Units) -> colormaps.Stretch:
    """The colour stretch ``form`` asks for: percentiles of the cells, or the absolute
    limits typed in the roughness unit (InputError if unusable)."""
    log = bool(form.log)
    if form.stretch == "absolute":
        per = units.rough_per
        lo, hi = float(form.range_lo), float(form.range_hi)
        if log and lo <= 0:
            raise InputError("a log colour scale needs a lowest θ above 0")
        return colormaps.Stretch("absolute", lo * per, hi * per, log=log)
    p_lo, p_hi = (float(v) for v in form.percentiles)
    return colormaps.Stretch("percentile", p_lo, p_hi, log=log)


def form_of(settings: MapSettings, choices: GridChoices, like: MapForm,
            layers: tuple[str, ...] | None = None) -> MapForm:
    """``like`` showing ``settings``: the grid as a preset entry or ``free``, the model
    by its label, ``auto`` for the model's own colour map; an absolute stretch's limits
    in the roughness unit (3 digits), a percentile stretch on the slider. The colour
    layer changes only when ``layers`` (the dropdown's entries; None: any) has it."""
    u = choices.units
    auto = resolve_colormap("auto", settings.model)
    label = COLOUR_LAYER_LABELS[settings.layer]
    st = settings.stretch
    form = replace(
        like, grid=grid_choice(settings.cell_size, choices.values),
        grid_free=u.length(settings.cell_size), model=MODEL_LABELS[settings.model],
        keep_outliers=bool(settings.keep_outliers), axis=settings.axis,
        min_points=int(settings.min_points), display=settings.display,
        threshold=float(settings.threshold),
        colormap="auto" if settings.colormap == auto else settings.colormap,
        layer=label if layers is None or label in layers else like.layer,
        stretch=st.mode, log=bool(st.log))
    if st.mode == "absolute":
        form = replace(form, range_lo=round_limit(u.rough(st.lo)),
                       range_hi=round_limit(u.rough(st.hi)))
    else:
        form = replace(form, percentiles=(float(st.lo), float(st.hi)))
    return slider_ends(form)
