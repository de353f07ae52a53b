"""The Profile tab: two clicks on the rock give a roughness profile, de-noised by
wavelets, with its fractal dimension (core: profile, wavelets, fractal).

The pure part (:class:`ProfileSettings`, :func:`analyse`, :func:`profiles_csv`)
needs no viser. :func:`mount` adds the tab; its work runs as jobs on the worker: the
clicks arrive through the host's click event (:meth:`ProfileFeature.on_pick`),
:class:`DenoiseJob` redoes the kept profiles with new settings,
:class:`ClearProfilesJob`, :class:`ProfilePlotJob` and :class:`ProfilesCsvJob`
clear, redraw and download them, and :class:`RestoreProfilesJob` brings a saved
view's profiles back.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar, cast

import numpy as np
import viser

from rough_viewer.app.binding import Binding, assign
from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.host import Host, Pick
from rough_viewer.app.layout import PLOTLY_CONFIG
from rough_viewer.app.limits import MAX_PROFILES
from rough_viewer.app.markup import md
from rough_viewer.app.scene import MARKER
from rough_viewer.app.units import Units
from rough_viewer.app.worker import Job, Run
from rough_viewer.profiles.extraction import Profile, extract_profile, patch_box
from rough_viewer.profiles.fractal import (
    RoughnessLength,
    Windows,
    detrend,
    parse_windows,
    roughness_length,
)
from rough_viewer.profiles.wavelets import Denoised, denoise_result
from rough_viewer.report.view import ProfilePick, View
from rough_viewer.visual.app import panel_aspect
from rough_viewer.visual.profiles import profile_figure
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
    threshold_rule: ThresholdRule = "fixed"
    threshold_mode: Mode = "hard"
    band_half_width: float | None = None
    """Metres; None = the local point spacing."""
    detrend: int | None = None
    """Degree of the polynomial trend removed from the heights before de-noising and
    fitting; None = none (each window of the fit is detrended linearly anyway)."""
    windows: Windows = None
    """Window lengths of the roughness-length fit, metres, or a rule (None: the
    default, 3-30 % of the profile in log steps; ``"paper"``: 3-10 %)."""
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


def analyse(points: np.ndarray | LoadedCloud, start: np.ndarray, end: np.ndarray,
            settings: ProfileSettings) -> ProfileAnalysis:
    """Extract the profile between ``start`` and ``end`` (file frame, metres) and
    de-noise it; raises InputError/ValueError from the core for bad picks.
    ``points``: (N, 3) metres, or a loaded cloud, which gives the points of the
    line's patch (:meth:`~rough_viewer.app.cloud.LoadedCloud.points_covering`: of
    a campaign, every point of its file there)."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    if isinstance(points, LoadedCloud):
        points = points.points_covering(*patch_box(start, end,
                                                   band_half_width=settings.band_half_width))
    prof = extract_profile(points, start, end, band_half_width=settings.band_half_width)
    return redo(prof, settings)


def redo(profile: Profile, settings: ProfileSettings) -> ProfileAnalysis:
    """De-noise and fit an extracted profile again with other settings (its trend
    removed first where ``settings.detrend`` asks)."""
    used = profile
    if settings.detrend is not None:
        used = replace(profile, heights=detrend(profile.heights, profile.spacing,
                                                degree=settings.detrend))
    den = denoise_result(used.heights, wavelet=settings.wavelet, level=settings.level,
                         decomposition=settings.decomposition,
                         threshold=settings.threshold_rule, mode=settings.threshold_mode)
    return ProfileAnalysis(used, den,
                           roughness_length(used.heights, used.spacing, windows=settings.windows),
                           roughness_length(den.heights, used.spacing, windows=settings.windows),
                           settings,
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
    rows = [f"| # | length ({u.label}) | band ± ({u.rough_label}) | σ noise ({u.rough_label}) "
            "| D raw | D de-noised |",
            "|---:|---:|---:|---:|---:|---:|"]
    for k, a in enumerate(analyses, start=1):
        rows.append(f"| {k} | {u.length(a.profile.length):.4g} | "
                    f"{u.rough(a.source.band_half_width):.3g} | {u.rough(a.denoised.sigma):.3g} | "
                    f"{a.raw_fit.dimension:.3f} | {a.denoised_fit.dimension:.3f} |")
    notes = [f"- ⚠ **P{k}**: {md(w)}" for k, a in enumerate(analyses, start=1)
             for w in a.warnings]
    if notes:
        rows += ["", *notes]
        if any("trend" in w for a in analyses for w in a.warnings):
            rows.append("- *Remove trend* (degree 2) takes a curved profile's trend off "
                        "before the fit.")
    return "\n".join(rows)


def windows_of(text: str, metres_per_unit: float) -> Windows:
    """The windows typed in the tab (lengths in the cloud's unit) in metres, or a rule;
    InputError names what is wrong.

    >>> windows_of("default", 1.0), windows_of("20, 40, 80", 1e-3)
    (None, (0.02, 0.04, 0.08))
    """
    windows = parse_windows(text, metres_per_unit)
    return None if windows == "default" else windows


def windows_label(units: Units) -> str:
    """The label of the windows field."""
    return f"Fit windows ({units.label})"


def band_label(units: Units) -> str:
    """The label of the band half-width control."""
    return f"Band half-width ({units.label})"


class ProfileBinding(Binding):
    """The tab's de-noising controls and :class:`ProfileSettings`."""

    def __init__(self, p: ProfileFeature) -> None:
        self.p = p

    def read(self) -> ProfileSettings:
        """The settings the controls show (the band typed in the cloud's unit, in
        metres). InputError for a value that is not one of a control's options."""
        p = self.p
        bw = float(p.band.value) * p.units.per
        return ProfileSettings(
            wavelet=p.wavelet.value, level=int(p.level.value),
            detrend=detrend_of(p.detrend.value),
            decomposition=cast(Decomposition, p.decomposition.value),
            threshold_rule=cast(ThresholdRule, p.threshold_rule.value),
            threshold_mode=cast(Mode, p.threshold_mode.value),
            band_half_width=bw if bw > 0 else None,
            windows=windows_of(p.windows.value, p.units.per),
            exaggeration=exaggeration_of(p.exaggeration.value))

    def show(self, settings: ProfileSettings, *, band: bool = False) -> None:
        """Put the de-noising controls to ``settings`` without queuing work (the band
        too when ``band``)."""
        p = self.p
        with self.quietly():
            for handle, value in ((p.wavelet, settings.wavelet),
                                  (p.decomposition, settings.decomposition),
                                  (p.threshold_rule, settings.threshold_rule),
                                  (p.threshold_mode, settings.threshold_mode),
                                  (p.detrend, detrend_choice(settings.detrend))):
                if value in handle.options:
                    assign(handle, value)
            if p.level.min <= settings.level <= p.level.max:
                assign(p.level, int(settings.level))
            width = (settings.band_half_width or 0.0) / p.units.per
            if band and (p.band.max is None or width <= p.band.max):
                assign(p.band, float(width))

    def follow(self, units: Units) -> None:
        """The band is typed in the new cloud's unit."""
        p = self.p
        self.write(p.band, label=band_label(units), max=units.length(MAX_BAND_M))
        self.write(p.windows, label=windows_label(units))


@dataclass(eq=False)
class ProfileFeature:
    """Handles and state of the Profile tab (the worker changes the state)."""

    host: Host
    on: viser.GuiCheckboxHandle
    wavelet: viser.GuiDropdownHandle[str]
    level: viser.GuiSliderHandle[int]
    decomposition: viser.GuiDropdownHandle[str]
    threshold_rule: viser.GuiDropdownHandle[str]
    threshold_mode: viser.GuiDropdownHandle[str]
    band: viser.GuiNumberHandle[float]
    detrend: viser.GuiDropdownHandle[str]
    windows: viser.GuiTextHandle
    """Window lengths of the fractal fit typed in the cloud's unit, or default / paper."""
    exaggeration: viser.GuiDropdownHandle[str]
    note: viser.GuiMarkdownHandle
    plot: viser.GuiPlotlyHandle
    clear: viser.GuiButtonHandle
    download: viser.GuiButtonHandle
    binding: ProfileBinding = field(init=False)
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

    def __post_init__(self) -> None:
        self.binding = ProfileBinding(self)

    @property
    def units(self) -> Units:
        """How the shown cloud's lengths are shown (the band is typed in its unit)."""
        return self.host.session.shown.loaded.units

    def refresh(self) -> None:
        """Redraw the table and the plot (at the height its builder laid it out for)."""
        u = self.units
        self.binding.write(self.note, content=summary_markdown(self.items, u))
        self.binding.show_figure(self.plot, profile_figure(
            self.items, exaggeration=exaggeration_of(self.exaggeration.value),
            length_unit=(u.label, u.per), height_unit=(u.rough_label, u.rough_per)))

    def on_pick(self, pick: Pick) -> bool:
        """A click while profile mode is on: the start, then the end of a profile
        (worker). False when profile mode is off."""
        if not self.on.value:
            return False
        host = self.host
        k = len(self.items)
        if self.start is None:
            self.start = (pick.xyz, pick.local)
            self.nodes.append([host.scene.marker(f"/profiles/{k}/start", pick.local,
                                                 f"{MARKER} P{k + 1}")])
            self.binding.write(self.note, content="Start picked; click the end of the profile.")
            return True
        (p0, _l0), self.start = self.start, None
        try:
            a = analyse(host.session.shown.loaded, p0, pick.xyz,
                        self.binding.read())
        except InputError as exc:
            host.scene.remove(self.nodes.pop())
            host.show_error(f"profile: {exc}")
            return True
        self.nodes[-1] += self._draw(a, k, None, np.asarray(pick.local, dtype=np.float64))
        self._keep(a)
        return True

    def _draw(self, a: ProfileAnalysis, k: int, start: np.ndarray | None,
              end: np.ndarray) -> list[viser.SceneNodeHandle]:
        """Scene nodes of profile ``k``: the line along the surface (its de-noised
        samples, drawn on both sides of the rock a little off the surface so the
        points in front cannot hide it) and markers at its ends (labels: on top,
        sized in pixels); ``start`` None when its marker is drawn already. Points in
        the display frame."""
        scene = self.host.scene
        colour = hex_to_rgb(PROFILE_COLOURS[k % len(PROFILE_COLOURS)])
        on_surface = self.host.session.shown.loaded.to_local(
            a.source.sample_xyz(a.surface_heights()))
        lift = float(scene.point_size) + 3.0 * float(a.denoised.sigma)
        nodes: list[viser.SceneNodeHandle] = []
        if start is not None:
            nodes.append(scene.marker(f"/profiles/{k}/start", start, f"{MARKER} P{k + 1}"))
        nodes += scene.surface_line(f"/profiles/{k}/line", on_surface, a.profile.frame.normal,
                                    lift, colour)
        nodes.append(scene.marker(f"/profiles/{k}/end", end, f"{MARKER} P{k + 1} end"))
        return nodes

    def _keep(self, a: ProfileAnalysis) -> None:
        """Keep ``a`` (its nodes are the last of :attr:`nodes`), drop the oldest beyond
        :data:`MAX_PROFILES`, redraw the panel."""
        self.items.append(a)
        while len(self.items) > MAX_PROFILES:
            self.items.pop(0)
            self.host.scene.remove(self.nodes.pop(0))
        self.refresh()

    def add_profile(self, start: np.ndarray, end: np.ndarray,
                    settings: ProfileSettings) -> ProfileAnalysis:
        """Analyse the line from ``start`` to ``end`` (file frame, metres) with
        ``settings`` and keep it, drawn as two clicks draw it (a saved view's
        profiles come back this way; worker).

        Raises InputError from the core (e.g. no points near the line).
        """
        a = analyse(self.host.session.shown.loaded, start, end, settings)
        self._show(a)
        return a

    def _show(self, a: ProfileAnalysis) -> None:
        """Draw ``a`` with markers at both ends of its line on the shown cloud, and
        keep it."""
        loaded = self.host.session.shown.loaded
        ends = (loaded.to_local(np.asarray(p, dtype=np.float64))
                for p in (a.source.start, a.source.end))
        self.nodes.append(self._draw(a, len(self.items), *ends))
        self._keep(a)

    def on_cloud(self) -> None:
        """Another cloud is shown (worker): profiles belong to their cloud, so the
        kept ones go (those of a scan put aside for the board lesson wait for it and
        come back with it); the band is typed in the new cloud's unit."""
        self.binding.follow(self.units)
        session = self.host.session
        new = session.shown.loaded
        if new is self.cloud:
            return
        old, kept = self.cloud, list(self.items)
        self.cloud = new
        self.clear_all()
        stashed = session.stashed.loaded if session.stashed is not None else None
        if kept and old is not None and stashed is old:
            self.aside = (old, kept)
        elif self.aside is not None and self.aside[0] is new:
            for a in self.aside[1]:
                self._show(a)
            self.aside = None
        elif self.aside is not None and stashed is not self.aside[0]:
            self.aside = None  # the scan put aside is gone

    def clear_all(self) -> None:
        for nodes in self.nodes:
            self.host.scene.remove(nodes)
        self.items, self.nodes, self.start = [], [], None
        self.refresh()

    # ------------------------------------------------------------------ saved views
    def snapshot(self) -> dict[str, Any]:
        """The kept profiles as a saved view's entries (file frame, metres)."""
        picks = []
        for a in self.items:
            s = a.settings
            p0, p1 = a.source.start, a.source.end
            picks.append(ProfilePick(
                start=(float(p0[0]), float(p0[1]), float(p0[2])),
                end=(float(p1[0]), float(p1[1]), float(p1[2])),
                band_half_width_m=None if s.band_half_width is None else float(s.band_half_width),
                wavelet=s.wavelet, level=int(s.level), decomposition=s.decomposition,
                threshold_rule=s.threshold_rule, mode=s.threshold_mode, detrend=s.detrend))
        return {"profiles": tuple(picks[-MAX_PROFILES:])}

    def restore(self, view: View) -> Job[Host] | None:
        return RestoreProfilesJob(self, view.profiles) if view.profiles else None

    def figures(self) -> dict[str, viser.GuiPlotlyHandle]:
        return {"profile": self.plot}


def settings_of_pick(pick: ProfilePick) -> ProfileSettings:
    """The settings a saved view's profile was analysed with."""
    return ProfileSettings(wavelet=pick.wavelet, level=pick.level,
                           decomposition=pick.decomposition, threshold_rule=pick.threshold_rule,
                           threshold_mode=pick.mode, band_half_width=pick.band_half_width_m,
                           detrend=pick.detrend)


@dataclass(frozen=True)
class DenoiseJob(Job[Host]):
    """De-noise and fit every kept profile again with the tab's settings."""

    p: ProfileFeature = field(compare=False)
    lane: ClassVar[str] = "profile-denoise"

    @property
    def title(self) -> str:
        return "profile de-noising"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        p = self.p
        redone = []
        try:
            settings = p.binding.read()
            points = ctx.session.shown.loaded
            for a in p.items:
                run.check()
                if settings.band_half_width != a.settings.band_half_width:
                    # another band holds other points: extract the line again
                    redone.append(analyse(points, a.source.start, a.source.end, settings))
                else:
                    redone.append(redo(a.source, settings))
        except InputError as exc:
            # the kept profiles stay as they were: so do the controls that made them
            if p.items:
                p.binding.show(p.items[0].settings)
            p.failed = True
            ctx.show_error(f"profile: {exc}",
                           kept="The profiles and their settings are kept as they were.")
            return
        yield "denoise"
        p.items = redone
        p.refresh()
        if p.failed:  # the error of an earlier setting no longer holds
            p.failed = False
            ctx.clear_error()
        yield "plot"


@dataclass(frozen=True)
class ClearProfilesJob(Job[Host]):
    """Remove every kept profile."""

    p: ProfileFeature = field(compare=False)
    lane: ClassVar[str] = "profile-clear"
    cancels: ClassVar[frozenset[str]] = frozenset({"profile-denoise", "profile-plot"})

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        self.p.clear_all()
        yield "clear"


@dataclass(frozen=True)
class ProfilePlotJob(Job[Host]):
    """Redraw the profile plot (vertical exaggeration changed)."""

    p: ProfileFeature = field(compare=False)
    lane: ClassVar[str] = "profile-plot"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        self.p.refresh()
        yield "plot"


@dataclass(frozen=True)
class ProfilesCsvJob(Job[Host]):
    """Send the kept profiles as CSV to one browser (or every browser)."""

    p: ProfileFeature = field(compare=False)
    client_id: int | None
    lane: ClassVar[str] = "profile-csv"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        data = profiles_csv(self.p.items).encode()
        yield "csv"
        clients = ctx.clients()
        targets = list(clients.values()) if self.client_id is None else \
            [c for cid, c in clients.items() if cid == self.client_id]
        for client in targets:  # saved at once, as the Export folder's downloads are
            client.send_file_download("profiles.csv", data, save_immediately=True)
        yield "send"


@dataclass(frozen=True)
class RestoreProfilesJob(Job[Host]):
    """A saved view's profiles: the tab's controls as the first had them, then each
    profile extracted and de-noised again with its own settings."""

    p: ProfileFeature = field(compare=False)
    picks: tuple[ProfilePick, ...] = ()
    lane: ClassVar[str] = "profile-restore"

    @property
    def title(self) -> str:
        return "restoring the view's profiles"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        if self.picks:
            self.p.binding.show(settings_of_pick(self.picks[0]), band=True)
        failed: list[str] = []
        for k, pick in enumerate(self.picks, start=1):
            run.check()
            try:
                self.p.add_profile(np.asarray(pick.start), np.asarray(pick.end),
                                   settings_of_pick(pick))
            except InputError as exc:
                failed.append(f"profile {k}: {exc}")
            yield f"profile {k}"
        if failed:
            more = f" (and {len(failed) - 1} more)" if len(failed) > 1 else ""
            ctx.show_error(f"saved view: {failed[0]}{more}",
                           kept="The other profiles are shown.")


def mount(host: Host) -> ProfileFeature:
    """Add the Profile tab: controls, plot, CSV download; clicks go here in profile mode."""
    gui = host.gui
    units = host.session.shown.loaded.units
    first = profile_figure([], exaggeration=exaggeration_of("auto"),
                           length_unit=(units.label, units.per),
                           height_unit=(units.rough_label, units.rough_per))
    with host.tab("Profile"):
        p = ProfileFeature(
            host=host,
            on=gui.add_checkbox("Profile mode", False,
                                hint="Clicks pick the two ends of a profile line."),
            wavelet=gui.add_dropdown("Wavelet", WAVELETS, initial_value="db3"),
            level=gui.add_slider("Level", min=1, max=6, step=1, initial_value=3),
            decomposition=gui.add_dropdown("Decomposition", DECOMPOSITIONS,
                                           initial_value="dwt"),
            threshold_rule=gui.add_dropdown("Threshold rule", THRESHOLD_RULES,
                                            initial_value="fixed"),
            threshold_mode=gui.add_dropdown("Threshold mode", ("hard", "soft"),
                                            initial_value="hard"),
            band=gui.add_number(band_label(units), 0.0, min=0.0,
                                max=units.length(MAX_BAND_M), step=0.001,
                                hint="0 = the local point spacing"),
            detrend=gui.add_dropdown(
                "Remove trend", DETRENDS, initial_value="none",
                hint="Take a polynomial trend of this degree off the heights before "
                "de-noising and the fractal fit (for curved faces: D below 1 is the mark "
                "of a trend)."),
            windows=gui.add_text(
                windows_label(units), "default",
                hint="Window lengths of the roughness-length fit of D, separated by commas, "
                "or 'default' (3-30 % of the profile) or 'paper' (the paper's 3-10 %); "
                "larger windows for smooth or curved profiles whose D comes out below 1."),
            exaggeration=gui.add_dropdown(
                "Vertical exaggeration", EXAGGERATIONS, initial_value="auto",
                hint="auto: the height axis spans the profile's relief; 1× is true scale; "
                "E× draws heights E times as long as distances along the line."),
            note=gui.add_markdown(summary_markdown([], units)),
            plot=gui.add_plotly(first, config=PLOTLY_CONFIG,  # axes in the cloud's unit
                                aspect=1.29 if first.layout.height is None
                                else panel_aspect(first)),
            clear=gui.add_button("Clear profiles"),
            download=gui.add_button("Download CSV"),
        )
    p.cloud = host.session.shown.loaded
    host.allow(p.on, p.wavelet, p.level, p.decomposition, p.threshold_rule, p.threshold_mode,
               p.band, p.detrend, p.windows, p.exaggeration, p.clear, p.download)
    b = p.binding
    b.on_change([p.wavelet, p.level, p.decomposition, p.threshold_rule, p.threshold_mode,
                 p.detrend, p.band, p.windows], lambda _h: host.submit(DenoiseJob(p)))
    b.on_change([p.exaggeration], lambda _h: host.submit(ProfilePlotJob(p)))
    b.on_change([p.clear], lambda _h: host.submit(ClearProfilesJob(p)))

    @p.download.on_click
    def _(event: viser.GuiEvent[viser.GuiButtonHandle]) -> None:
        host.submit(ProfilesCsvJob(p, event.client_id))

    host.on_click(p.on_pick)
    host.on_cloud(p.on_cloud)
    return p
