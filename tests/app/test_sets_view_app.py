"""Issue 31 item 11 (the Sets tab): a saved view keeps the tab's settings, whether the
sets were shown and the selected set and joint; ``serve --view`` (``apply_view``) on a
fresh app puts them back and finds the same sets, on a small rock mass of three
planted sets."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.app.features.sets import SetsFeature, set_option
from rough_viewer.app.markup import md
from rough_viewer.app.server import build_app
from rough_viewer.app.settings import MapSettings
from rough_viewer.structure.sets import SetOptions, joint_sets
from rough_viewer.synthetic.joints import generate_rock_mass
from tests.app.protocol import pick, shown_colours
from tests.app.test_joints_app import SMALL_ROCK_MASS, G


@pytest.fixture(scope="module")
def rock():
    return generate_rock_mass(SMALL_ROCK_MASS)


def _app(server, rock):
    return build_app(server, rock.cloud, prefetch=False, variogram=False, presets=(G,),
                     settings=MapSettings(cell_size=G), max_display=60_000)


def _per_set(sets) -> list[int]:
    """Joints of each set, set 1 first."""
    return np.bincount(sets.joints.set_id, minlength=sets.n_sets + 1)[1:].tolist()


def test_a_saved_view_keeps_the_sets_settings_and_selection_and_finds_them_again(
        server, rock, tmp_path):
    import viser

    from rough_viewer.app.views import apply_view, view_of
    from rough_viewer.report.view import InputRef, SetsView, load_view, save_view
    from rough_viewer.visual.sets import point_colours

    app = _app(server, rock)
    try:
        assert app.wait_idle(120)
        f = app.feature(SetsFeature)
        ref_in = InputRef(path=str(tmp_path / "rock.npy"), sha256="0" * 64, size_bytes=1)
        # hidden at the defaults: the view holds no sets (older versions read it)
        assert view_of(app.host, ref_in, camera=None).sets is None
        f.roughness.value = 3.0
        f.cone.value = 15.0
        f.min_angle.value = 25.0
        f.max_sets.value = 5
        f.colour_by.value = "joint"
        f.poles.value = "per patch"
        assert app.wait_idle(60) and f.sets is None  # not shown: nothing found
        f.on.value = True
        assert app.wait_idle(120) and f.sets is not None
        res, loaded = app.session.shown.result, app.session.shown.loaded
        options = SetOptions(max_roughness=0.03 * G, cone_deg=15.0, min_angle_deg=25.0,
                             max_sets=5)
        ref = joint_sets(res, rock.cloud, options)  # the library, independently
        assert ref.n_sets == 3 and sorted(_per_set(ref)) == sorted(
            s.joints for s in SMALL_ROCK_MASS.sets)
        assert f.sets.n_sets == ref.n_sets and _per_set(f.sets) == _per_set(ref)
        # select the second joint of set 2 by a click on the rock
        jt = ref.joints
        want = int(np.flatnonzero(jt.set_id == 2)[1]) + 1
        rows = np.flatnonzero(ref.cell_joint[res.point_cell[loaded.display_index]] == want)
        target = loaded.display_points[rows[len(rows) // 2]].astype(float)
        normal = jt.normal[want - 1]
        assert pick(app, target + 0.02 * normal, -normal) is None
        assert (f.selected_set, f.selected_joint) == (2, want)
        saved = load_view(save_view(tmp_path / "v.json", view_of(app.host, ref_in,
                                                                   camera=None)),
                          check=False).view
        assert saved.sets == SetsView(shown=True, colour_by="joint", poles="patch",
                                      roughness_pct=3.0, cone_deg=15.0, min_angle_deg=25.0,
                                      max_sets=5, selected_set=2, selected_joint=want)
    finally:
        app.stop()
    other_server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    other = _app(other_server, rock)
    try:
        assert other.wait_idle(120)
        g = other.feature(SetsFeature)
        assert (g.on.value, g.cone.value, g.sets) == (False, 20.0, None)
        apply_view(other.host, saved)
        assert other.wait_idle(120) and list(other.host.errors) == []
        assert (g.on.value, g.colour_by.value, g.poles.value, g.roughness.value,
                g.cone.value, g.min_angle.value, g.max_sets.value) == \
            (True, "joint", "per patch", 3.0, 15.0, 25.0, 5)
        assert g.sets is not None and g.sets.n_sets == ref.n_sets
        assert _per_set(g.sets) == _per_set(ref)
        np.testing.assert_array_equal(g.sets.cell_joint, ref.cell_joint)
        assert (g.selected_set, g.selected_joint) == (2, want)
        assert g.selected.value == set_option(ref, 2)
        assert g.joint_info.content.startswith(md(f"Joint {want} (set 2)"))
        shown = other.session.shown
        np.testing.assert_array_equal(
            shown_colours(other),
            point_colours(ref, shown.result.point_cell[shown.loaded.display_index],
                          by="joint"))
        # a view with the sets hidden at other settings: the controls follow, the
        # sets go off and the map's colours come back
        apply_view(other.host, saved.with_(sets=SetsView(cone_deg=30.0)))
        assert other.wait_idle(120) and list(other.host.errors) == []
        assert (g.on.value, g.cone.value, g.colour_by.value) == (False, 30.0, "set")
        assert other.map.overlay is None
    finally:
        other.stop()
        other_server.stop()
