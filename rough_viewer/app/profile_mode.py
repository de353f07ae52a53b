"""Profile mode: two clicks on the rock give a roughness profile, de-noised by
wavelets, with its fractal dimension (core: profile, wavelets, fractal).

The pure part (:class:`ProfileSettings`, :func:`analyse`, :func:`profiles_csv`)
needs no viser; :func:`add_profile_tab` puts the controls in the GUI.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass

import numpy as np

from rough_viewer.profiles.extraction import Profile, extract_profile
from rough_viewer.profiles.fractal import RoughnessLength, roughness_length
from rough_viewer.profiles.wavelets import Denoised, denoise_result
from rough_viewer.vocabulary import PROFILE_COLOURS, THRESHOLD_RULES, hex_to_rgb

WAVELETS = ("db3", "db2", "db4", "sym4", "haar")


@dataclass(frozen=True)
class ProfileSettings:
    """De-noising and extraction options (see :mod:`rough_viewer.profiles.wavelets`)."""

    wavelet: str = "db3"
    level: int = 3
    decomposition: str = "dwt"
    threshold: str = "fixed"
    mode: str = "hard"
    band_half_width: float | None = None
    """Metres; None = the local point spacing."""
    exaggeration: float = 1.0
    """Vertical exaggeration of the profile plot (display only)."""


@dataclass(frozen=True)
class ProfileAnalysis:
    """One profile with its de-noised version and both roughness-length fits."""

    profile: Profile
    denoised: Denoised
    raw_fit: RoughnessLength
    denoised_fit: RoughnessLength
    settings: ProfileSettings


def analyse(points: np.ndarray, start, end, settings: ProfileSettings) -> ProfileAnalysis:
    """Extract the profile between ``start`` and ``end`` (file frame, metres) and
    de-noise it; raises InputError/ValueError from the core for bad picks."""
    prof = extract_profile(points, np.asarray(start, float), np.asarray(end, float),
                           band_half_width=settings.band_half_width)
    return redo(prof, settings)


def redo(profile: Profile, settings: ProfileSettings) -> ProfileAnalysis:
    """De-noise and fit an extracted profile again with other settings."""
    den = denoise_result(profile.heights, wavelet=settings.wavelet, level=settings.level,
                         decomposition=settings.decomposition,  # type: ignore[arg-type]
                         threshold=settings.threshold,  # type: ignore[arg-type]
                         mode=settings.mode)  # type: ignore[arg-type]
    return ProfileAnalysis(profile, den, roughness_length(profile.heights, profile.spacing),
                           roughness_length(den.heights, profile.spacing), settings)


def profiles_csv(analyses: list[ProfileAnalysis]) -> str:
    """CSV of every sample of every profile (metres, file frame)."""
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["profile", "distance_m", "height_m", "denoised_m", "x", "y", "z",
                "D_raw", "D_denoised"])
    for k, a in enumerate(analyses, start=1):
        xyz = a.profile.sample_xyz()
        for i, d in enumerate(a.profile.distance):
            w.writerow([k, f"{d:.6f}", f"{a.profile.heights[i]:.7g}",
                        f"{a.denoised.heights[i]:.7g}", f"{xyz[i, 0]:.4f}", f"{xyz[i, 1]:.4f}",
                        f"{xyz[i, 2]:.4f}", f"{a.raw_fit.dimension:.4f}",
                        f"{a.denoised_fit.dimension:.4f}"])
    return out.getvalue()


def summary_markdown(analyses: list[ProfileAnalysis]) -> str:
    if not analyses:
        return "Tick *Profile mode* and click two points on the rock."
    rows = ["| # | length (m) | σ noise (mm) | D raw | D de-noised |", "|---|---|---|---|---|"]
    for k, a in enumerate(analyses, start=1):
        rows.append(f"| {k} | {a.profile.length:.2f} | {1e3 * a.denoised.sigma:.2f} | "
                    f"{a.raw_fit.dimension:.3f} | {a.denoised_fit.dimension:.3f} |")
    return "\n".join(rows)


def add_profile_tab(app, tabs) -> None:
    """Profile tab: controls, plot, CSV download; clicks go here in profile mode."""
    from rough_viewer.visual.profiles import profile_figure

    gui = app.server.gui
    with tabs.add_tab("Profile"):
        on = gui.add_checkbox("Profile mode", False,
                              hint="Clicks pick the two ends of a profile line.")
        wavelet = gui.add_dropdown("Wavelet", WAVELETS, initial_value="db3")
        level = gui.add_slider("Level", min=1, max=6, step=1, initial_value=3)
        decomp = gui.add_dropdown("Decomposition", ("dwt", "wp"), initial_value="dwt")
        rule = gui.add_dropdown("Threshold rule", THRESHOLD_RULES, initial_value="fixed")
        mode = gui.add_dropdown("Threshold mode", ("hard", "soft"), initial_value="hard")
        band = gui.add_number("Band half-width (m)", 0.0, min=0.0, max=10.0, step=0.001,
                              hint="0 = the local point spacing")
        exag = gui.add_slider("Vertical exaggeration", min=1.0, max=20.0, step=0.5,
                              initial_value=1.0)
        note = gui.add_markdown(summary_markdown([]))
        plot = gui.add_plotly(profile_figure([], exaggeration=1.0), aspect=1.2)
        clear = gui.add_button("Clear profiles")
        download = gui.add_button("Download CSV")

    state = {"start": None, "items": [], "nodes": [],
             "controls": {"on": on, "wavelet": wavelet, "level": level, "decomposition": decomp,
                          "threshold": rule, "mode": mode, "band": band,
                          "exaggeration": exag, "note": note, "plot": plot, "clear": clear,
                          "download": download}}
    app.profile = state

    def settings() -> ProfileSettings:
        bw = float(band.value)
        return ProfileSettings(wavelet=wavelet.value, level=int(level.value),
                               decomposition=decomp.value, threshold=rule.value,
                               mode=mode.value, band_half_width=bw if bw > 0 else None,
                               exaggeration=float(exag.value))

    def refresh() -> None:
        note.content = summary_markdown(state["items"])
        plot.figure = profile_figure(state["items"], exaggeration=float(exag.value))

    def rework(_event=None) -> None:
        s = settings()
        try:
            state["items"] = [redo(a.profile, s) for a in state["items"]]
        except Exception as exc:  # noqa: BLE001 - shown to the user
            app.show_error(f"profile: {exc}")
            return
        refresh()

    for control in (wavelet, level, decomp, rule, mode):
        control.on_update(rework)
    exag.on_update(lambda _e: refresh())

    @clear.on_click
    def _(_event) -> None:
        for node in state["nodes"]:
            node.remove()
        state.update(start=None, items=[], nodes=[])
        refresh()

    @download.on_click
    def _(event) -> None:
        data = profiles_csv(state["items"]).encode()
        target = event.client if event.client is not None else app.server
        target.send_file_download("profiles.csv", data)

    def on_pick(point_file: np.ndarray, local: np.ndarray) -> bool:
        """Handle a click in profile mode; False when profile mode is off."""
        if not on.value:
            return False
        k = len(state["items"])
        colour = hex_to_rgb(PROFILE_COLOURS[k % len(PROFILE_COLOURS)])
        if state["start"] is None:
            state["start"] = (point_file, local)
            state["nodes"].append(app.server.scene.add_icosphere(
                f"/profiles/{k}/start", radius=0.02, color=colour, position=tuple(local)))
            note.content = "Start picked; click the end of the profile."
            return True
        (p0, l0), state["start"] = state["start"], None
        try:
            loaded = app.shown.loaded
            a = analyse(loaded.cloud.xyz(), p0, point_file, settings())
        except Exception as exc:  # noqa: BLE001 - bad picks are reported, not raised
            app.show_error(f"profile: {exc}")
            return True
        state["items"].append(a)
        seg = np.array([[l0, local]], dtype=np.float32)
        state["nodes"].append(app.server.scene.add_line_segments(
            f"/profiles/{k}/line", seg, colour, thickness=4.0, thickness_units="screen"))
        state["nodes"].append(app.server.scene.add_label(
            f"/profiles/{k}/label", f"P{k + 1}", position=tuple(local)))
        refresh()
        return True

    app.profile_pick = on_pick
    app.profile_settings = settings
