"""Profile mode: two clicks on the rock give a roughness profile, de-noised by
wavelets, with its fractal dimension (core: profile, wavelets, fractal).

The pure part (:class:`ProfileSettings`, :func:`analyse`, :func:`profiles_csv`)
needs no viser. :func:`mount` adds the "Profile" tab; its work runs as jobs on
the app's worker: the clicks arrive through the app's pick job
(:meth:`ProfileMode.on_pick`), :class:`DenoiseJob` redoes the kept profiles with
new settings, :class:`ClearProfilesJob`, :class:`ProfilePlotJob` and
:class:`ProfilesCsvJob` clear, redraw and download them.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, ClassVar, cast

import numpy as np
import viser

from rough_viewer.app import scene
from rough_viewer.app.jobs import Pick
from rough_viewer.app.layout import PLOTLY_CONFIG
from rough_viewer.app.limits import MAX_PROFILES
from rough_viewer.app.markup import md
from rough_viewer.app.state import LoadedCloud, Units
from rough_viewer.app.worker import Job, Run
from rough_viewer.profiles.extraction import Profile, extract_profile
from rough_viewer.profiles.fractal import RoughnessLength, detrend, roughness_length
from rough_viewer.profiles.wavelets import Denoised, denoise_result
from rough_viewer.vocabulary import (
    DECOMPOSITIONS,
    PROFILE_COLOURS,
    THRESHOLD_RULES,
    Decomposition,
    InputError,
    Mode,
    ThresholdRule,
    hex_to_rgb,
)

if TYPE_CHECKING:
    from rough_viewer.app.server import App

WAVELETS = ("db3", "db2", "db4", "sym4", "haar")
#: Widest band half-width the Profile tab takes, metres.
MAX_BAND_M = 10.0
#: Vertical exaggeration choices of the profile plot: "auto" (fitted height range)
#: or E times (heights drawn E times as long as distances along the line).
EXAGGERATIONS: tuple[str, ...] = ("auto", "1×", "2×", "5×", "10×", "20×", "50×", "100×")
#: Trend removal choices: "none" or the degree of the polynomial taken off the
#: heights before de-noising and fitting (:func:`rough_viewer.profiles.fractal.detrend`).
DETRENDS: tuple[str, ...] = ("none", "degree 1", "degree 2", "degree 3")


def detrend_of(choice: str) -> int | None:
    """The degree of a trend-removal entry: None for ``none``.

    >>> detrend_of("none"), detrend_of("degree 2")
    (None, 2)
    """
    if choice not in DETRENDS:
        raise InputError(f"unknown trend removal {choice!r}")
    return None if choice == "none" else int(choice.split()[1])


def detrend_choice(degree: int | None) -> str:
    """The dropdown entry of a degree (None: ``none``)."""
    return "none" if degree is None else f"degree {int(degree)}"


def exaggeration_of(choice: str) -> float | None:
    """The exaggeration of a dropdown entry: None for ``auto``, else E of ``"E×"``.

    >>> exaggeration_of("auto"), exaggeration_of("20×")
    (None, 20.0)
    """
    if choice not in EXAGGERATIONS:
        raise InputError(f"unknown vertical exaggeration {choice!r}")
    return None if choice == "auto" else float(choice.rstrip("×"))


@dataclass(frozen=True)
class ProfileSettings:
    """De-noising and extraction options (see :mod:`rough_viewer.profiles.wavelets`)."""

    wavelet: str = "db3"
    level: int = 3
    decomposition: Decomposition = "dwt"
    threshold: ThresholdRule = "fixed"
    mode: Mode = "hard"
    band_half_width: float | None = None
    """Metres; None = the local point spacing."""
    detrend: int | None = None
    """Degree of the polynomial trend removed from the heights before de-noising and
    fitting; None = none (each window of the fit is detrended linearly anyway)."""
    exaggeration: float | None = None
    """Vertical exaggeration of the profile plot (display only): None = the height
    axis fitted to the data (default); a number E draws 1 mm of height E times as
    long as 1 mm along the line (1 = true scale)."""


@dataclass(frozen=True)
class ProfileAnalysis:
    """One profile with its de-noised version and both roughness-length fits."""

    profile: Profile
    """The analysed profile: the extracted one, minus its trend where one is removed."""
    denoised: Denoised
    raw_fit: RoughnessLength
    denoised_fit: RoughnessLength
    settings: ProfileSettings
    extracted: Profile | None = None
    """The profile as extracted (None: the same as :attr:`profile`)."""

    @property
    def source(self) -> Profile:
        """The extracted profile (before any trend removal)."""
        return self.extracted if self.extracted is not None else self.profile

    def surface_heights(self) -> np.ndarray:
        """The de-noised heights with the removed trend put back (metres): where the
        de-noised line lies on the rock."""
        return np.asarray(self.denoised.heights) + (np.asarray(self.source.heights)
                                                    - np.asarray(self.profile.heights))

    @property
    def warnings(self) -> tuple[str, ...]:
        """The plausibility warnings of both fits, each once."""
        return tuple(dict.fromkeys(self.raw_fit.warnings + self.denoised_fit.warnings))


def analyse(points: np.ndarray, start: np.ndarray, end: np.ndarray,
            settings: ProfileSettings) -> ProfileAnalysis:
    """Extract the profile between ``start`` and ``end`` (file frame, metres) and
    de-noise it; raises InputError/ValueError from the core for bad picks."""
    prof = extract_profile(points, np.asarray(start, float), np.asarray(end, float),
                           band_half_width=settings.band_half_width)
    return redo(prof, settings)


def redo(profile: Profile, settings: ProfileSettings) -> ProfileAnalysis:
    """De-noise and fit an extracted profile again with other settings (its trend
    removed first where ``settings.detrend`` asks)."""
    used = profile
    if settings.detrend is not None:
        used = replace(profile, heights=detrend(profile.heights, profile.spacing,
                                                degree=settings.detrend))
    den = denoise_result(used.heights, wavelet=settings.wavelet, level=settings.level,
                         decomposition=settings.decomposition, threshold=settings.threshold,
                         mode=settings.mode)
    return ProfileAnalysis(used, den, roughness_length(used.heights, used.spacing),
                           roughness_length(den.heights, used.spacing), settings,
                           extracted=None if used is profile else profile)


def profiles_csv(analyses: list[ProfileAnalysis]) -> str:
    """CSV of every sample of every profile (metres, file frame): the analysed
    heights (minus the trend where one is removed), the de-noised ones, and the
    sample's point on the rock."""
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["profile", "distance_m", "height_m", "denoised_m", "x", "y", "z",
                "D_raw", "D_denoised"])
    for k, a in enumerate(analyses, start=1):
        xyz = a.source.sample_xyz()
        for i, d in enumerate(a.profile.distance):
            # full precision (the shortest exact text): a millimetre scan's relief is in
            # the 5th decimal of a metre
            w.writerow([k, *(repr(float(v)) for v in (
                d, a.profile.heights[i], a.denoised.heights[i], *xyz[i])),
                f"{a.raw_fit.dimension:.4f}", f"{a.denoised_fit.dimension:.4f}"])
    return out.getvalue()


def summary_markdown(analyses: list[ProfileAnalysis], units: Units | None = None) -> str:
    """The kept profiles as a Markdown table (numbers only): lengths in the cloud's
    unit, the noise in its roughness unit (m and mm by default)."""
    if not analyses:
        return "Tick *Profile mode* and click two points on the rock."
    u = units or Units("m")
    rows = [f"| # | length ({u.label}) | σ noise ({u.rough_label}) | D raw | D de-noised |",
            "|---:|---:|---:|---:|---:|"]
    for k, a in enumerate(analyses, start=1):
        rows.append(f"| {k} | {u.length(a.profile.length):.4g} | {u.rough(a.denoised.sigma):.3g} | "
                    f"{a.raw_fit.dimension:.3f} | {a.denoised_fit.dimension:.3f} |")
    notes = [f"- ⚠ **P{k}**: {md(w)}" for k, a in enumerate(analyses, start=1)
             for w in a.warnings]
    if notes:
        rows += ["", *notes]
        if any("trend" in w for a in analyses for w in a.warnings):
            rows.append("- *Remove trend* (degree 2) takes a curved profile's trend off "
                        "before the fit.")
    return "\n".join(rows)


def band_label(units: Units) -> str:
    """The label of the band half-width control."""
    return f"Band half-width ({units.label})"


@dataclass
class ProfileMode:
    """Handles and state of the Profile tab (the worker changes the state)."""

    app: App
    on: viser.GuiCheckboxHandle
    wavelet: viser.GuiDropdownHandle[str]
    level: viser.GuiSliderHandle[int]
    decomposition: viser.GuiDropdownHandle[str]
    threshold: viser.GuiDropdownHandle[str]
    mode: viser.GuiDropdownHandle[str]
    band: viser.GuiNumberHandle[float]
    detrend: viser.GuiDropdownHandle[str]
    exaggeration: viser.GuiDropdownHandle[str]
    note: viser.GuiMarkdownHandle
    plot: viser.GuiPlotlyHandle
    clear: viser.GuiButtonHandle
    download: viser.GuiButtonHandle
    items: list[ProfileAnalysis] = field(default_factory=list)
    """The kept profiles, oldest first (at most :data:`MAX_PROFILES`)."""
    start: tuple[np.ndarray, np.ndarray] | None = None
    """The first click of a profile being picked: (file frame, display frame)."""
    nodes: list[list[viser.SceneNodeHandle]] = field(default_factory=list)
    """Scene nodes of each kept profile (the pending start's marker last)."""
    cloud: LoadedCloud | None = None
    """The cloud the kept profiles were picked on."""
    failed: bool = False
    """The last de-noising failed (its error is shown until one succeeds)."""
    aside: tuple[LoadedCloud, list[ProfileAnalysis]] | None = None
    """The profiles of the scan put aside while the board lesson is shown."""

    @property
    def units(self) -> Units:
        """How the shown cloud's lengths are shown (the band is typed in its unit)."""
        return self.app.shown.loaded.units

    def settings(self) -> ProfileSettings:
        """The de-noising settings the controls show (the band in metres)."""
        bw = float(self.band.value) * self.units.per
        return ProfileSettings(
            wavelet=self.wavelet.value, level=int(self.level.value),
            detrend=detrend_of(self.detrend.value),
            decomposition=cast(Decomposition, self.decomposition.value),
            threshold=cast(ThresholdRule, self.threshold.value),
            mode=cast(Mode, self.mode.value),
            band_half_width=bw if bw > 0 else None,
            exaggeration=exaggeration_of(self.exaggeration.value))

    def show_settings(self, settings: ProfileSettings) -> None:
        """Put the de-noising controls to ``settings`` without queuing work."""
        from rough_viewer.app.layout import assign, quietly

        with quietly(self.app._local):
            for handle, value in ((self.wavelet, settings.wavelet),
                                  (self.decomposition, settings.decomposition),
                                  (self.threshold, settings.threshold), (self.mode, settings.mode),
                                  (self.detrend, detrend_choice(settings.detrend))):
                if value in handle.options:
                    assign(handle, value)
            assign(self.level, int(settings.level))

    def refresh(self) -> None:
        """Redraw the table and the plot (at the height its builder laid it out for)."""
        from rough_viewer.visual.app import panel_aspect
        from rough_viewer.visual.profiles import profile_figure

        u = self.units
        self.note.content = summary_markdown(self.items, u)
        fig = profile_figure(self.items, exaggeration=exaggeration_of(self.exaggeration.value),
                             length_unit=(u.label, u.per),
                             height_unit=(u.rough_label, u.rough_per))
        if fig.layout.height is not None:
            self.plot.aspect = panel_aspect(fig)
        self.plot.figure = fig

    def on_pick(self, app: App, pick: Pick) -> bool:
        """A click while profile mode is on: the start, then the end of a profile
        (runs in the app's pick job). False when profile mode is off."""
        if not self.on.value:
            return False
        k = len(self.items)
        if self.start is None:
            self.start = (pick.xyz, pick.local)
            self.nodes.append([scene.marker(app.server, f"/profiles/{k}/start", pick.local,
                                            f"{scene.MARKER} P{k + 1}")])
            self.note.content = "Start picked; click the end of the profile."
            return True
        (p0, _l0), self.start = self.start, None
        try:
            a = analyse(app.shown.loaded.cloud.xyz(), p0, pick.xyz, self.settings())
        except (InputError, ValueError) as exc:
            for node in self.nodes.pop():
                node.remove()
            app.show_error(f"profile: {exc}")
            return True
        self.nodes[-1] += self._draw(app, a, k, None, np.asarray(pick.local, dtype=np.float64))
        self._keep(a)
        return True

    def _draw(self, app: App, a: ProfileAnalysis, k: int, start: np.ndarray | None,
              end: np.ndarray) -> list[viser.SceneNodeHandle]:
        """Scene nodes of profile ``k``: the line along the surface (its de-noised
        samples, drawn on both sides of the rock a little off the surface so the
        points in front cannot hide it) and markers at its ends (labels: on top,
        sized in pixels); ``start`` None when its marker is drawn already. Points in
        the display frame."""
        colour = hex_to_rgb(PROFILE_COLOURS[k % len(PROFILE_COLOURS)])
        on_surface = app.shown.loaded.to_local(a.source.sample_xyz(a.surface_heights()))
        lift = float(app.gui.point_size.value) + 3.0 * float(a.denoised.sigma)
        nodes: list[viser.SceneNodeHandle] = []
        if start is not None:
            nodes.append(scene.marker(app.server, f"/profiles/{k}/start", start,
                                      f"{scene.MARKER} P{k + 1}"))
        nodes += scene.surface_line(app.server, f"/profiles/{k}/line", on_surface,
                                    a.profile.frame.normal, lift, colour)
        nodes.append(scene.marker(app.server, f"/profiles/{k}/end", end,
                                  f"{scene.MARKER} P{k + 1} end"))
        return nodes

    def _keep(self, a: ProfileAnalysis) -> None:
        """Keep ``a`` (its nodes are the last of :attr:`nodes`), drop the oldest beyond
        :data:`MAX_PROFILES`, redraw the panel."""
        self.items.append(a)
        while len(self.items) > MAX_PROFILES:
            self.items.pop(0)
            for node in self.nodes.pop(0):
                node.remove()
        self.refresh()

    def add_profile(self, app: App, start: np.ndarray, end: np.ndarray,
                    settings: ProfileSettings) -> ProfileAnalysis:
        """Analyse the line from ``start`` to ``end`` (file frame, metres) with
        ``settings`` and keep it, drawn as two clicks draw it (a saved view's
        profiles come back this way; worker thread).

        Raises InputError or ValueError from the core (e.g. no points near the line).
        """
        a = analyse(app.shown.loaded.cloud.xyz(), start, end, settings)
        self._show(app, a)
        return a

    def _show(self, app: App, a: ProfileAnalysis) -> None:
        """Draw ``a`` with markers at both ends of its line on the shown cloud, and
        keep it."""
        ends = (app.shown.loaded.to_local(np.asarray(p, dtype=np.float64))
                for p in (a.source.start, a.source.end))
        self.nodes.append(self._draw(app, a, len(self.items), *ends))
        self._keep(a)

    def on_cloud(self, app: App) -> None:
        """Another cloud is shown (worker thread): profiles belong to their cloud, so
        the kept ones go (those of a scan put aside for the board lesson wait for it
        and come back with it); the band is typed in the new cloud's unit."""
        self.band.label = band_label(self.units)
        self.band.max = self.units.length(MAX_BAND_M)
        new = app.shown.loaded
        if new is self.cloud:
            return
        old, kept = self.cloud, list(self.items)
        self.cloud = new
        self.clear_all()
        stashed = app.stashed.loaded if app.stashed is not None else None
        if kept and old is not None and stashed is old:
            self.aside = (old, kept)
        elif self.aside is not None and self.aside[0] is new:
            for a in self.aside[1]:
                self._show(app, a)
            self.aside = None
        elif self.aside is not None and stashed is not self.aside[0]:
            self.aside = None  # the scan put aside is gone

    def clear_all(self) -> None:
        for nodes in self.nodes:
            for node in nodes:
                node.remove()
        self.items, self.nodes, self.start = [], [], None
        self.refresh()


@dataclass(frozen=True)
class DenoiseJob(Job["App"]):
    """De-noise and fit every kept profile again with ``settings``."""

    mode: ProfileMode = field(compare=False)
    settings: ProfileSettings
    lane: ClassVar[str] = "profile-denoise"

    @property
    def title(self) -> str:
        return "profile de-noising"

    def stages(self, ctx: App, run: Run) -> Iterator[str]:
        redone = []
        try:
            for a in self.mode.items:
                run.check()
                redone.append(redo(a.source, self.settings))
        except (InputError, ValueError) as exc:
            # the kept profiles stay as they were: so do the controls that made them
            if self.mode.items:
                self.mode.show_settings(self.mode.items[0].settings)
            self.mode.failed = True
            ctx.show_error(f"profile: {exc}",
                           kept="The profiles and their settings are kept as they were.")
            return
        yield "denoise"
        self.mode.items = redone
        self.mode.refresh()
        if self.mode.failed:  # the error of an earlier setting no longer holds
            self.mode.failed = False
            ctx.clear_error()
        yield "plot"


@dataclass(frozen=True)
class ClearProfilesJob(Job["App"]):
    """Remove every kept profile."""

    mode: ProfileMode = field(compare=False)
    lane: ClassVar[str] = "profile-clear"
    cancels: ClassVar[frozenset[str]] = frozenset({"profile-denoise", "profile-plot"})

    def stages(self, ctx: App, run: Run) -> Iterator[str]:
        self.mode.clear_all()
        yield "clear"


@dataclass(frozen=True)
class ProfilePlotJob(Job["App"]):
    """Redraw the profile plot (vertical exaggeration changed)."""

    mode: ProfileMode = field(compare=False)
    lane: ClassVar[str] = "profile-plot"

    def stages(self, ctx: App, run: Run) -> Iterator[str]:
        self.mode.refresh()
        yield "plot"


@dataclass(frozen=True)
class ProfilesCsvJob(Job["App"]):
    """Send the kept profiles as CSV to one browser (or every browser)."""

    mode: ProfileMode = field(compare=False)
    client_id: int | None
    lane: ClassVar[str] = "profile-csv"

    def stages(self, ctx: App, run: Run) -> Iterator[str]:
        data = profiles_csv(self.mode.items).encode()
        yield "csv"
        client = ctx.server.get_clients().get(self.client_id) \
            if self.client_id is not None else None
        target: Any = client if client is not None else ctx.server
        target.send_file_download("profiles.csv", data)
        yield "send"


def mount(app: App) -> ProfileMode:
    """Add the Profile tab: controls, plot, CSV download; clicks go here in profile mode."""
    m = _add_controls(app)
    m.cloud = app.shown.loaded
    _wire(app, m)
    app.click_handlers.append(m.on_pick)
    app.cloud_handlers.append(m.on_cloud)
    return m


def _add_controls(app: App) -> ProfileMode:
    """Stage 1: the tab's controls, registered for values from browsers."""
    from rough_viewer.visual.profiles import profile_figure

    gui = app.server.gui
    with app.gui.tabs.add_tab("Profile"):
        m = ProfileMode(
            app=app,
            on=gui.add_checkbox("Profile mode", False,
                                hint="Clicks pick the two ends of a profile line."),
            wavelet=gui.add_dropdown("Wavelet", WAVELETS, initial_value="db3"),
            level=gui.add_slider("Level", min=1, max=6, step=1, initial_value=3),
            decomposition=gui.add_dropdown("Decomposition", DECOMPOSITIONS,
                                           initial_value="dwt"),
            threshold=gui.add_dropdown("Threshold rule", THRESHOLD_RULES,
                                       initial_value="fixed"),
            mode=gui.add_dropdown("Threshold mode", ("hard", "soft"),
                                  initial_value="hard"),
            band=gui.add_number(band_label(app.shown.loaded.units), 0.0, min=0.0,
                                max=app.shown.loaded.units.length(MAX_BAND_M), step=0.001,
                                hint="0 = the local point spacing"),
            detrend=gui.add_dropdown(
                "Remove trend", DETRENDS, initial_value="none",
                hint="Take a polynomial trend of this degree off the heights before "
                "de-noising and the fractal fit (for curved faces: D below 1 is the mark "
                "of a trend)."),
            exaggeration=gui.add_dropdown(
                "Vertical exaggeration", EXAGGERATIONS, initial_value="auto",
                hint="auto: the height axis spans the profile's relief; 1× is true scale; "
                "E× draws heights E times as long as distances along the line."),
            note=gui.add_markdown(summary_markdown([])),
            plot=gui.add_plotly(profile_figure([]), config=PLOTLY_CONFIG, aspect=1.29),
            clear=gui.add_button("Clear profiles"),
            download=gui.add_button("Download CSV"),
        )
    app.controls.allow(m.on, m.wavelet, m.level, m.decomposition, m.threshold, m.mode,
                       m.band, m.detrend, m.exaggeration, m.clear, m.download)
    return m


def _wire(app: App, m: ProfileMode) -> None:
    """Stage 2: each control queues its job."""

    def denoise(_event: object) -> None:
        if app.syncing:  # the controls are being put back, not changed by a user
            return
        app.submit(DenoiseJob(m, m.settings()))

    def replot(_event: object) -> None:
        app.submit(ProfilePlotJob(m))

    def clear(_event: object) -> None:
        app.submit(ClearProfilesJob(m))

    for control in (m.wavelet, m.level, m.decomposition, m.threshold, m.mode, m.detrend):
        control.on_update(denoise)
    m.exaggeration.on_update(replot)
    m.clear.on_click(clear)

    @m.download.on_click
    def _(event: viser.GuiEvent[viser.GuiButtonHandle]) -> None:
        app.submit(ProfilesCsvJob(m, event.client_id))
