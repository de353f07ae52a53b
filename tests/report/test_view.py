"""Saved views: save and reload give the same settings; every field of an untrusted
file is checked; a changed or moved input is reported (issue 15)."""

from __future__ import annotations

import json
import os
import shutil

import pytest

from rough_viewer.report.view import (
    MAX_VIEW_BYTES,
    Camera,
    ColourSettings,
    ProfilePick,
    View,
    ZoneSettings,
    file_sha256,
    input_ref,
    load_view,
    save_view,
)
from rough_viewer.visual.colormaps import Stretch
from rough_viewer.vocabulary import InputError


@pytest.fixture
def scan(tmp_path):
    folder = tmp_path / "project"
    folder.mkdir()
    p = folder / "scan.xyz"
    p.write_text("0 0 0\n1 0 0\n0 1 0\n1 1 0.1\n")
    return p


def full_view(scan) -> View:
    return View(
        input=input_ref(scan), cell_size_m=0.125, min_points=4, axis="y", model="e_ols",
        units="mm", threshold=0.12,
        colour=ColourSettings(colormap="cividis", mode="binary",
                              stretch=Stretch.absolute_mm(0.5, 20, log=True)),
        panels=("table", "histogram", "across-scales"),
        profiles=(ProfilePick(start=(1.0, 2.0, 3.0), end=(4.0, 5.5, 3.0), band_half_width_m=0.002,
                              wavelet="sym4", level=4, decomposition="wp",
                              threshold_rule="penalized-high", mode="soft", detrend=2),
                  ProfilePick(start=(0.0, 0.0, 0.0), end=(0.0, 1.0, 0.0))),
        zones=ZoneSettings(map="hybrid", connectivity="face", min_cells=5, selected=2),
        camera=Camera(position=(10.0, -5.0, 3.0), look_at=(0.0, 0.0, 1.0), fov_deg=40.0),
    )


def test_save_and_reload_give_the_same_view(scan, tmp_path):
    view = full_view(scan)
    path = save_view(tmp_path / "v.json", view)
    loaded = load_view(path)
    assert loaded.view == view
    assert loaded.view.colour == ColourSettings("cividis", "binary",
                                                Stretch("absolute", 0.0005, 0.02, log=True))
    assert loaded.view.panels == ("table", "histogram", "across-scales")
    assert loaded.input_check.status == "unchanged" and loaded.input_check.path == scan
    assert loaded.software.startswith("rough_viewer ")
    doc = json.loads(path.read_text())
    assert doc["format"] == "rough_viewer.view" and doc["version"] == 1
    assert doc["input"]["relative_path"] == os.path.join("project", "scan.xyz")
    # minimal views take the defaults
    small = View(input=input_ref(scan), cell_size_m=0.5, min_points=3)
    assert load_view(save_view(tmp_path / "small.json", small)).view == small


def test_hash_streams_and_matches_hashlib(tmp_path, monkeypatch):
    import hashlib

    import rough_viewer.report.view as view_module

    monkeypatch.setattr(view_module, "HASH_BLOCK", 1000)
    data = os.urandom(10_500)
    (tmp_path / "f.bin").write_bytes(data)
    seen = []
    assert file_sha256(tmp_path / "f.bin", progress=lambda d, t: seen.append(d)) == \
        hashlib.sha256(data).hexdigest()
    assert seen == [1000 * k for k in range(1, 11)] + [10_500]  # 11 reads, never whole


def test_changed_input_is_reported(scan, tmp_path):
    path = save_view(tmp_path / "v.json", full_view(scan))
    scan.write_text(scan.read_text().replace("0.1", "0.2"))  # same size, other content
    check = load_view(path).input_check
    assert check.status == "changed" and check.path == scan and "changed" in check.message
    scan.write_text("0 0 0\n")
    assert load_view(path).input_check.status == "changed"


def test_moved_and_missing_input(scan, tmp_path):
    view = full_view(scan)
    save_view(scan.parent / "v.json", view)
    moved = tmp_path / "moved"
    shutil.move(scan.parent, moved)
    check = load_view(moved / "v.json").input_check
    assert check.status == "moved" and check.path == moved / "scan.xyz"
    assert "moved" in check.message
    (moved / "scan.xyz").unlink()
    check = load_view(moved / "v.json").input_check
    assert check.status == "missing" and check.path is None
    assert load_view(moved / "v.json", check=False).input_check.status == "not_checked"


def test_save_refuses_overwrite_and_the_input(scan, tmp_path):
    view = full_view(scan)
    save_view(tmp_path / "v.json", view)
    with pytest.raises(InputError, match="exists"):
        save_view(tmp_path / "v.json", view)
    save_view(tmp_path / "v.json", view, force=True)
    with pytest.raises(InputError, match="is the input file"):
        save_view(scan, view, force=True)
    assert scan.read_text().startswith("0 0 0")


def _doc(scan, tmp_path):
    path = save_view(tmp_path / "good.json", full_view(scan))
    return json.loads(path.read_text())


BAD = {
    "wrong type": (lambda d: d["grid"].update(cell_size_m="0.5"), "grid.cell_size_m must be a number"),
    "bool as number": (lambda d: d["grid"].update(min_points=True), "grid.min_points must be a whole"),
    "zero grid": (lambda d: d["grid"].update(cell_size_m=0), "grid.cell_size_m must lie in"),
    "min points 2": (lambda d: d["grid"].update(min_points=2), "grid.min_points must lie in [3"),
    "threshold": (lambda d: d.update(threshold=1.5), "threshold must lie in [0, 1]"),
    "model": (lambda d: d.update(model="rms"), "model must be one of odr, ols, hybrid, e_ols"),
    "axis": (lambda d: d["grid"].update(axis="w"), "grid.axis must be one of"),
    "units": (lambda d: d.update(units="furlong"), "units must be one of m, mm, ft, us-ft"),
    "colormap": (lambda d: d["colour"].update(colormap="jet"), "colour.colormap must be one of"),
    "range falls": (lambda d: d["colour"].update(range=[0.02, 0.001]), "colour.range must rise"),
    "log from 0": (lambda d: d["colour"].update(range=[0.0, 0.02]), "must start above 0"),
    "unknown key": (lambda d: d.update(script="alert(1)"), "unknown key 'script'"),
    "unknown nested": (lambda d: d["colour"].update(opacity=1), "colour has an unknown key"),
    "hash": (lambda d: d["input"].update(sha256="xyz"), "input.sha256 must be 64"),
    "path NUL": (lambda d: d["input"].update(path="a\x00b"), "input.path must be a string"),
    "panel name": (lambda d: d.update(panels=["<img src=x>"]), "panels[0] must be a short"),
    "too many profiles": (lambda d: d.update(profiles=d["profiles"] * 60), "at most 100"),
    "profile point": (lambda d: d["profiles"][0].update(start=[1, 2]), "profiles[0].start must be"),
    "huge coordinate": (lambda d: d["profiles"][0].update(end=[1e300, 0, 0]), "must lie in"),
    "wavelet": (lambda d: d["profiles"][0].update(wavelet="../../etc"), "profiles[0].wavelet"),
    "level": (lambda d: d["profiles"][0].update(level=99), "profiles[0].level must lie in"),
    "detrend": (lambda d: d["profiles"][0].update(detrend=9), "profiles[0].detrend must lie in"),
    "detrend text": (lambda d: d["profiles"][0].update(detrend="2"),
                     "profiles[0].detrend must be a whole"),
    "zone id": (lambda d: d["zones"].update(selected=0), "zones.selected must lie in"),
    "measure point": (lambda d: d.update(measures=[{"start": [0, 0], "end": [1, 1, 1]}]),
                      "measures[0].start must be a list of three numbers"),
    "measure key": (lambda d: d.update(measures=[{"start": [0, 0, 0], "end": [1, 1, 1],
                                                  "colour": 1}]), "measures[0] has an unknown"),
    "direction step": (lambda d: d.update(directions={"step_deg": 0}),
                       "directions.step_deg must lie in [1, 90]"),
    "direction tin": (lambda d: d.update(directions={"tin": "yes"}),
                      "directions.tin must be true or false"),
    "selection quaternion": (lambda d: d.update(selection={
        "position": [0, 0, 0], "wxyz": [0, 0, 0, 0], "fov_rad": 0.9, "aspect": 1.5,
        "height_px": 800, "corner_a": [0, 0], "corner_b": [1, 1]}),
        "selection.wxyz must be a unit quaternion"),
    "sets cone": (lambda d: d.update(sets={"cone_deg": 0.5}),
                  "sets.cone_deg must lie in [1, 90], got 0.5"),
    "sets roughness": (lambda d: d.update(sets={"roughness_pct": 1e308}),
                       "sets.roughness_pct must lie in [0.1, 50]"),
    "sets min angle": (lambda d: d.update(sets={"min_angle_deg": -1}),
                       "sets.min_angle_deg must lie in [0, 90], got -1"),
    "sets max sets": (lambda d: d.update(sets={"max_sets": 10**9}),
                      "sets.max_sets must lie in [1, 20], got 1000000000"),
    "sets max sets float": (lambda d: d.update(sets={"max_sets": 2.5}),
                            "sets.max_sets must be a whole number"),
    "sets colour": (lambda d: d.update(sets={"colour_by": "<script>"}),
                    "sets.colour_by must be one of set, joint, patch"),
    "sets poles": (lambda d: d.update(sets={"poles": "per cell"}),
                   "sets.poles must be one of cell, patch, joint"),
    "sets shown": (lambda d: d.update(sets={"shown": 1}), "sets.shown must be true or false"),
    "sets selected": (lambda d: d.update(sets={"selected_set": 0}),
                      "sets.selected_set must lie in [1, 20], got 0"),
    "sets joint": (lambda d: d.update(sets={"selected_joint": -3}),
                   "sets.selected_joint must lie in [1, 10000000], got -3"),
    "sets key": (lambda d: d.update(sets={"smoothing_deg": 5}),
                 "sets has an unknown key 'smoothing_deg'"),
    "sets not an object": (lambda d: d.update(sets=[1]), "sets must be an object"),
    "zone rule": (lambda d: d["zones"].update(threshold_rule="otsu"),
                  "zones.threshold_rule must be one of auto, slider"),
    "camera": (lambda d: d["camera"].update(fov_deg=0), "camera.fov_deg must lie in"),
    "newer": (lambda d: d.update(version=2), "made by a newer rough_viewer"),
    "format": (lambda d: d.update(format="other"), "format must be 'rough_viewer.view'"),
    "not an object": (lambda d: d.update(grid=[1, 2]), "grid must be an object"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_every_field_is_checked(scan, tmp_path, case):
    doc = _doc(scan, tmp_path)
    change, message = BAD[case]
    change(doc)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError) as info:
        load_view(path)
    text = str(info.value)
    assert message in text and str(path) in text and "\n" not in text


@pytest.mark.parametrize("content", ["{", '{"format": NaN}', "[" * 100_000 + "]" * 100_000,
                                     "\xff\xfe", "null"])
def test_not_a_view_is_one_line(tmp_path, content):
    path = tmp_path / "x.json"
    path.write_bytes(content.encode("utf-8", errors="surrogateescape")
                     if content != "\xff\xfe" else b"\xff\xfe")
    with pytest.raises(InputError) as info:
        load_view(path)
    assert "\n" not in str(info.value)


def test_oversized_view_refused_unread(tmp_path):
    path = tmp_path / "big.json"
    path.write_bytes(b" " * (MAX_VIEW_BYTES + 1))
    with pytest.raises(InputError, match="a view is at most"):
        load_view(path)


def test_with_validates(scan):
    view = full_view(scan)
    assert view.with_(threshold=0.2).threshold == 0.2
    with pytest.raises(InputError, match="threshold"):
        view.with_(threshold=-1.0)


# ----------------------------------------------------------------------------- crop


def test_a_crop_is_saved_and_reloaded(scan, tmp_path):
    from rough_viewer.io.crop import CropBox

    box = CropBox((0.1, -2.0, 0.0), (0.9, 2.0, 0.05), "remove")
    view = full_view(scan).with_(crop=box)
    path = save_view(tmp_path / "crop.json", view)
    doc = json.loads(path.read_text())
    assert doc["crop"] == {"min": [0.1, -2.0, 0.0], "max": [0.9, 2.0, 0.05], "mode": "remove"}
    assert load_view(path).view.crop == box
    assert load_view(path).view == view


def test_zone_threshold_rule_is_kept_and_old_views_keep_their_threshold(scan, tmp_path):
    """Issue 31 item 8: a view keeps the zones' threshold rule; a view saved before the
    rule existed read its zones at its own threshold: it reads as "slider"."""
    for rule in ("auto", "slider"):
        view = full_view(scan).with_(zones=ZoneSettings(threshold_rule=rule))
        assert load_view(save_view(tmp_path / f"{rule}.json", view)).view.zones.threshold_rule \
            == rule
    path = save_view(tmp_path / "old.json", full_view(scan))
    doc = json.loads(path.read_text())
    assert doc["zones"]["threshold_rule"] == "auto"
    del doc["zones"]["threshold_rule"]
    path.write_text(json.dumps(doc))
    assert load_view(path).view.zones.threshold_rule == "slider"


def test_measures_and_directions_are_saved_and_reloaded(scan, tmp_path):
    """Issue 31 item 11: a view keeps the measures and the directions settings; a view
    without them is written without the keys (older versions read it)."""
    from rough_viewer.report.view import DirectionsView, MeasurePick

    view = full_view(scan).with_(
        measures=(MeasurePick((1.0, 2.0, 3.0), (4.0, 6.0, 3.0), 3),),
        directions=DirectionsView(step_deg=30.0, spacing_m=0.004, tin=True, lines=False,
                                  measured=True))
    assert load_view(save_view(tmp_path / "v.json", view)).view == view
    from rough_viewer.report.view import SelectionView

    sel = view.with_(selection=SelectionView((1.0, -5.0, 2.0), (0.5, 0.5, 0.5, 0.5), 0.9, 1.5,
                                             800, (0.25, 0.3), (0.6, 0.75)))
    assert load_view(save_view(tmp_path / "s.json", sel)).view == sel
    doc = json.loads(save_view(tmp_path / "plain.json", full_view(scan)).read_text())
    assert "measures" not in doc and "directions" not in doc and "selection" not in doc


def test_the_sets_tab_is_saved_and_reloaded_and_old_views_read_as_none(scan, tmp_path):
    """Issue 31 item 11: a view keeps the Sets tab's settings and selection; a view
    without them is written without the key and reads as None (nothing to restore)."""
    from rough_viewer.report.view import SetsView

    sets = SetsView(shown=True, colour_by="joint", poles="patch", roughness_pct=3.5,
                    cone_deg=15.0, min_angle_deg=25.0, max_sets=4, selected_set=2,
                    selected_joint=7)
    view = full_view(scan).with_(sets=sets)
    path = save_view(tmp_path / "v.json", view)
    assert json.loads(path.read_text())["sets"] == {
        "shown": True, "colour_by": "joint", "poles": "patch", "roughness_pct": 3.5,
        "cone_deg": 15.0, "min_angle_deg": 25.0, "max_sets": 4, "selected_set": 2,
        "selected_joint": 7}
    assert load_view(path).view == view
    doc = json.loads(save_view(tmp_path / "plain.json", full_view(scan)).read_text())
    assert "sets" not in doc
    assert load_view(tmp_path / "plain.json").view.sets is None
    doc["sets"] = {"shown": True}  # the rest: the tab's defaults
    (tmp_path / "some.json").write_text(json.dumps(doc))
    got = load_view(tmp_path / "some.json").view.sets
    assert got == SetsView(shown=True) and (got.cone_deg, got.roughness_pct, got.max_sets) == \
        (20.0, 2.0, 6)


def test_views_without_a_crop_stay_as_before(scan, tmp_path):
    """A view saved today (no "crop" key) reads as uncropped; a view without a crop
    is written without the key, so older versions still read it; null is no crop."""
    path = save_view(tmp_path / "v.json", full_view(scan))
    doc = json.loads(path.read_text())
    assert "crop" not in doc and load_view(path).view.crop is None
    doc["crop"] = None
    path.write_text(json.dumps(doc))
    assert load_view(path).view.crop is None
    doc["crop"] = {"min": [0, 0, 0], "max": [1, 1, 1]}
    path.write_text(json.dumps(doc))
    assert load_view(path).view.crop.mode == "keep"


@pytest.mark.parametrize("crop, message", [
    ({"min": [2, 0, 0], "max": [1, 1, 1]}, "crop has its x minimum 2 above its maximum 1"),
    ({"min": [0, 0, 0], "max": [1, 1, 1], "mode": "cut"}, "crop.mode must be one of keep, remove"),
    ({"min": [0, 0, 0], "max": [1, 1, 1], "box": 1}, "crop has an unknown key 'box'"),
    ({"min": [0, 0], "max": [1, 1, 1]}, "crop.min must be a list of three numbers"),
    ({"max": [1, 1, 1]}, "crop lacks 'min'"),
    ({"min": [0, 0, float("inf")], "max": [1, 1, 1]}, "not valid JSON"),
])
def test_bad_crops_are_refused_naming_the_field(scan, tmp_path, crop, message):
    path = save_view(tmp_path / "v.json", full_view(scan))
    doc = json.loads(path.read_text())
    doc["crop"] = crop
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=message):
        load_view(path)
