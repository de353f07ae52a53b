"""The Map tab's rules as data (:mod:`rough_viewer.app.settings`), without viser.

The reference for the twin controls is the rule the app used before the rules were
data, written out again here: each control takes its change's value, then the
controls that follow the *last changed* control of their group move (the grid
dropdown and the free size; the slider, the typed percentiles and the typed limits).
"""

from __future__ import annotations

import random

import pytest

from rough_viewer.app.settings import (
    FORM_FIELDS,
    GridChoices,
    MapForm,
    MapSettings,
    apply,
    form_of,
    settings_of,
    settle,
)
from rough_viewer.app.units import Units
from rough_viewer.visual import colormaps
from rough_viewer.vocabulary import InputError

CHOICES = GridChoices.of((1.0, 0.5, 0.25), Units("m"))
FT = GridChoices.of((4 * 0.3048, 2 * 0.3048), Units("ft"))


def reference(form: MapForm, changes: list[tuple[str, object]], choices: GridChoices) -> dict:
    """The index-of-last-change rule, on a plain dict."""
    c = dict(vars(form))
    for name, value in changes:
        if name == "toggle":
            c["model"] = "OLS" if c["model"] == "ODR" else "ODR"
        else:
            c[name] = value
    last = {name: k for k, (name, _v) in enumerate(changes)}
    grid, free = last.get("grid", -1), last.get("grid_free", -1)
    if free > grid:
        c["grid"] = "free"
    elif grid >= 0 and c["grid"] in choices.values:
        c["grid_free"] = choices.units.length(choices.values[c["grid"]])
    typed = max(last.get("pct_lo", -1), last.get("pct_hi", -1))
    if typed > last.get("percentiles", -1):
        c["percentiles"] = tuple(sorted((float(c["pct_lo"]), float(c["pct_hi"]))))
    group = ("stretch", "percentiles", "pct_lo", "pct_hi", "range_lo", "range_hi")
    order = {k: last.get(k, -1) for k in group}
    latest = max(order, key=lambda k: order[k])
    if order[latest] >= 0 and latest != "stretch":
        c["stretch"] = "absolute" if latest in ("range_lo", "range_hi") else "percentile"
    c["pct_lo"], c["pct_hi"] = (float(v) for v in c["percentiles"])
    return c


def random_change(rng: random.Random) -> tuple[str, object]:
    name = rng.choice(("grid", "grid_free", "toggle", "percentiles", "pct_lo", "pct_hi",
                       "range_lo", "range_hi", "stretch", "threshold", "model"))
    value: object = {
        "grid": rng.choice((*CHOICES.values, "free")),
        "grid_free": rng.choice((0.3, 0.75, 2.0)),
        "toggle": True,
        "percentiles": (float(rng.randint(0, 40)), float(rng.randint(60, 100))),
        "pct_lo": float(rng.randint(0, 100)),
        "pct_hi": float(rng.randint(0, 100)),
        "range_lo": rng.choice((0.5, 1.0)),
        "range_hi": rng.choice((3.0, 4.0)),
        "stretch": rng.choice(("percentile", "absolute")),
        "threshold": rng.choice((0.05, 0.2)),
        "model": rng.choice(("ODR", "OLS", "Hybrid")),
    }[name]
    return name, value


def test_each_change_follows_the_last_change_rule() -> None:
    """2,000 random sequences of 1-6 changes, each settled before the next (as a
    person sees them): the pure rules give exactly what the old rule gives."""
    rng = random.Random(7)
    start = MapForm(grid="0.5", grid_free=0.5)
    for _ in range(2000):
        changes = [random_change(rng) for _ in range(rng.randint(1, 6))]
        want = start
        for change in changes:
            want = MapForm(**reference(want, [change], CHOICES))
        assert settle(start, tuple(changes), CHOICES) == want, changes


def test_changes_merged_in_one_job_read_what_the_person_saw() -> None:
    """A slider drag then a typed highest percentile, merged into one job: the typed
    field's partner is the slider's new end (14), as the person saw it, where the old
    rule read the field's stale 2."""
    changes = (("percentiles", (14.0, 99.0)), ("pct_hi", 60.0))
    assert settle(MapForm(), changes, CHOICES).percentiles == (14.0, 60.0)
    assert reference(MapForm(), list(changes), CHOICES)["percentiles"] == (2.0, 60.0)


def test_free_size_then_preset_and_back() -> None:
    f = apply(MapForm(grid="1"), ("grid_free", 0.3), CHOICES)
    assert (f.grid, f.grid_free) == ("free", 0.3)
    assert settings_of(f, CHOICES).cell_size == pytest.approx(0.3)
    f = apply(f, ("grid", "0.25"), CHOICES)
    assert (f.grid, f.grid_free) == ("0.25", 0.25)
    assert settings_of(f, CHOICES).cell_size == 0.25


def test_lengths_are_typed_in_the_clouds_unit() -> None:
    """An international-foot cloud: the dropdown shows 4 and 2 ft, a typed 3
    is 0.9144 m, and the limits are typed in the roughness unit (ft for ft)."""
    assert tuple(FT.values) == ("4", "2")
    f = apply(MapForm(grid="4"), ("grid_free", 3.0), FT)
    assert settings_of(f, FT).cell_size == pytest.approx(3 * 0.3048, rel=1e-12)
    f = apply(MapForm(log=False), ("range_hi", 0.01), FT)
    st = settings_of(f, FT).stretch
    assert (st.mode, st.hi) == ("absolute", pytest.approx(0.01 * 0.3048))


def test_toggle_flips_odr_and_ols_only() -> None:
    assert apply(MapForm(model="ODR"), ("toggle", True), CHOICES).model == "OLS"
    assert apply(MapForm(model="OLS"), ("toggle", True), CHOICES).model == "ODR"
    assert apply(MapForm(model="Hybrid"), ("toggle", True), CHOICES).model == "ODR"


def test_unusable_forms_are_refused_in_one_line() -> None:
    with pytest.raises(InputError, match="not one of this cloud's presets"):
        settings_of(MapForm(grid="0.3"), CHOICES)
    with pytest.raises(InputError, match="not one of its options"):
        settings_of(MapForm(grid="1", model="Fancy"), CHOICES)
    with pytest.raises(InputError, match="log colour scale needs a lowest"):
        settings_of(MapForm(grid="1", stretch="absolute", log=True, range_lo=0.0), CHOICES)
    with pytest.raises(ValueError, match="no control 'budget'"):
        apply(MapForm(), ("budget", 5), CHOICES)


@pytest.mark.parametrize("settings", [
    MapSettings(cell_size=0.5, model="ols", axis="z", min_points=6, display="binary",
                threshold=0.2, colormap="cividis", keep_outliers=True),
    MapSettings(cell_size=0.3, model="e_ols", layer="distance",
                stretch=colormaps.Stretch("absolute", 0.001, 0.004, log=False)),
    MapSettings(cell_size=1.0, stretch=colormaps.Stretch("percentile", 5.0, 95.0, log=True)),
])
def test_settings_shown_in_a_form_read_back_the_same(settings: MapSettings) -> None:
    form = form_of(settings, CHOICES, MapForm())
    assert settings_of(form, CHOICES) == settings
    assert form.grid == ("free" if settings.cell_size == 0.3 else f"{settings.cell_size:g}")


def test_a_layer_the_cloud_lacks_is_not_shown() -> None:
    s = MapSettings(cell_size=1.0, layer="rgb")
    kept = form_of(s, CHOICES, MapForm(), layers=("Roughness", "Distance to face plane"))
    assert kept.layer == MapForm().layer
    assert set(FORM_FIELDS) == set(vars(kept))
