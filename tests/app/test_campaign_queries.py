"""Spatial queries of a served campaign (issue 33 item 3): a profile picked on a COPC
campaign reads every point of the file near its line (the nodes of the index that
meet its patch, decoded in the reader sandbox), not the overview's; the result is
the profile of every point. A crop of a campaign holds every point of the file in
its box, and every analysis runs on them."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("lazrs")

from rough_viewer.app.campaign import (  # noqa: E402
    CampaignCrop,
    campaign_presets,
    open_campaign,
    points_in_box,
    read_overview,
)
from rough_viewer.app.features.crop import CropJob  # noqa: E402
from rough_viewer.app.features.profile import ProfileFeature, ProfileSettings, analyse  # noqa: E402
from rough_viewer.app.settings import MapSettings  # noqa: E402
from rough_viewer.grid.roughness import grid_roughness  # noqa: E402
from rough_viewer.io import load_points  # noqa: E402
from rough_viewer.io.copc.reader import decode_nodes, node_boxes, nodes_in_box, open_copc  # noqa: E402
from rough_viewer.io.crop import CropBox  # noqa: E402
from rough_viewer.profiles.extraction import extract_profile, patch_box  # noqa: E402
from rough_viewer.vocabulary import InputError  # noqa: E402
from tests.app.protocol import on_worker, pick  # noqa: E402
from tests.app.test_campaign_serve import CAP, N, _app  # noqa: E402
from tests.scale.helpers_scale import assert_same_cells  # noqa: E402
from tests.scale.test_tiles import _survey  # noqa: E402


@pytest.fixture(scope="module")
def survey(tmp_path_factory):
    return _survey(tmp_path_factory.mktemp("campaign-profile"), N, seed=11)


def _sorted_rows(a):
    return a[np.lexsort(a.T[::-1])]


def test_every_node_holds_its_points_inside_its_cube(survey):
    _, out, _ = survey
    copc = open_copc(out)
    lo, hi = node_boxes(copc)
    side = hi - lo
    assert np.allclose(side[:, 0], 2 * copc.halfsize / 2.0 ** copc.nodes["depth"])
    for k in range(copc.nodes.shape[0]):
        x, y, z = decode_nodes(copc, [k])
        p = np.column_stack([x, y, z])
        assert np.all(p >= lo[k] - copc.scales) and np.all(p <= hi[k] + copc.scales), k


def test_a_box_query_gives_every_point_of_the_file_inside_it(survey):
    """The points of the nodes that meet a box, cut to it, are exactly the file's
    points in the box (brute force over the points laspy reads), for boxes inside,
    across and outside the face."""
    _, out, xyz = survey
    campaign = open_campaign(out)
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    mid = 0.5 * (lo + hi)
    boxes = [(mid - 0.7, mid + 0.4), (lo - 1.0, lo + [2.0, 1.5, 9.0]), (lo - 1, hi + 1),
             (hi + 5.0, hi + 6.0)]
    for a, b in boxes:
        got = points_in_box(campaign, a, b)
        want = xyz[np.all((xyz >= a) & (xyz <= b), axis=1)]
        np.testing.assert_array_equal(_sorted_rows(got), _sorted_rows(want))
    small = nodes_in_box(campaign.copc, mid - 0.2, mid + 0.2)
    assert 0 < small.size < campaign.copc.nodes.shape[0]  # a query reads few nodes


def test_a_query_of_too_many_points_is_one_line(survey):
    _, out, xyz = survey
    campaign = open_campaign(out)
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    with pytest.raises(InputError, match="more than the 1,000 the app decodes") as info:
        points_in_box(campaign, lo, hi, decode_most=1_000, what="the profile")
    assert "\n" not in str(info.value) and "the profile needs" in str(info.value)
    with pytest.raises(InputError, match="more than 1,000 points of survey.copc.laz at once"):
        points_in_box(campaign, lo, hi, most=1_000, what="the profile")


def test_a_profile_on_a_campaign_is_the_profile_of_every_point(survey, tmp_path, monkeypatch):
    """Two ends on the face: the campaign app's profile (ProfileFeature.add_profile on
    a real viser server) equals extract_profile of all 60,000 points, and holds
    more points than the overview's profile. The reference reads the COPC file whole,
    in its order (the point spacing's estimate queries every k-th point of the
    patch, so the order counts)."""
    monkeypatch.setenv("ROUGH_VIEWER_CACHE", str(tmp_path / "cache"))
    _, out, _ = survey
    xyz = load_points(out, cache=False).xyz()
    campaign = open_campaign(out)
    overview = read_overview(campaign, CAP)
    presets = campaign_presets(overview, N)
    server, app, loaded = _app(campaign, overview, MapSettings(cell_size=presets[0]))
    try:
        assert app.wait_idle(300)
        lo, hi = xyz.min(axis=0), xyz.max(axis=0)
        pick = np.array([0.25, 0.5, 0.5]), np.array([0.75, 0.5, 0.5])
        # the ends on the surface: the file's points nearest the two spots of its box
        ends = [xyz[np.argmin(np.linalg.norm((xyz - (lo + f * (hi - lo)))[:, :2], axis=1))]
                for f in pick]
        settings = ProfileSettings()
        feature = app.feature(ProfileFeature)
        on_worker(app, lambda: feature.add_profile(ends[0], ends[1], settings), timeout=120)
        assert not app.host.errors, app.host.errors
        a = feature.items[-1]
        ref = extract_profile(xyz, ends[0], ends[1], band_half_width=settings.band_half_width)
        assert a.source.n_points == ref.n_points
        np.testing.assert_array_equal(a.source.heights, ref.heights)
        assert a.source.point_spacing == ref.point_spacing
        thin = extract_profile(overview.xyz(), ends[0], ends[1],
                               band_half_width=settings.band_half_width)
        assert thin.n_points < ref.n_points
        # the same through analyse() of the loaded cloud, and the box it reads
        b = analyse(loaded, ends[0], ends[1], settings)
        np.testing.assert_array_equal(b.source.heights, a.source.heights)
        box = patch_box(ends[0], ends[1], band_half_width=settings.band_half_width)
        assert np.all(box[0] <= np.minimum(*ends)) and np.all(box[1] >= np.maximum(*ends))
    finally:
        app.stop()
        server.stop()


def test_two_clicks_on_a_campaign_make_the_profile_of_every_point(survey, tmp_path,
                                                                  monkeypatch):
    """Profile mode and two clicks on the drawn overview (rays along the face's
    normal, as a browser sends them): the profile between the two points clicked is
    that of every point of the file."""
    monkeypatch.setenv("ROUGH_VIEWER_CACHE", str(tmp_path / "cache"))
    _, out, _ = survey
    xyz = load_points(out, cache=False).xyz()
    campaign = open_campaign(out)
    overview = read_overview(campaign, CAP)
    presets = campaign_presets(overview, N)
    server, app, loaded = _app(campaign, overview, MapSettings(cell_size=presets[0]))
    try:
        assert app.wait_idle(300)
        feature = app.feature(ProfileFeature)
        on_worker(app, lambda: setattr(feature.on, "value", True))
        pts = loaded.display_points.astype(np.float64)
        normal = loaded.plane.normal
        centre = pts.mean(axis=0)
        span = pts.max(axis=0) - pts.min(axis=0)
        ends = []
        for f in (-0.25, 0.25):
            target = centre + f * span * np.array([1.0, 0.0, 0.0])
            i = int(np.argmin(np.linalg.norm(pts - target, axis=1)))
            pick(app, pts[i] + 5.0 * normal, -normal)
            ends.append(loaded.to_file_frame(pts[i]))
        assert not app.host.errors, app.host.errors
        assert len(feature.items) == 1
        a = feature.items[0]
        ref = extract_profile(xyz, a.source.start, a.source.end)
        np.testing.assert_allclose(a.source.start, ends[0], atol=1e-6)
        assert a.source.n_points == ref.n_points
        np.testing.assert_array_equal(a.source.heights, ref.heights)
    finally:
        app.stop()
        server.stop()


def test_a_crop_of_a_campaign_holds_every_point_of_the_file_in_its_box(survey, tmp_path,
                                                                        monkeypatch):
    """The Select tab's crop (a CropJob on a real viser server) of a campaign: the
    cloud shown is every point of the file in the box (brute force), its map is
    grid_roughness of those points, the status counts them against the file's;
    a selection inside the crop keeps exactly its points; undoing the crop gives the
    campaign back; a box of too many points is one line and the campaign stays."""
    monkeypatch.setenv("ROUGH_VIEWER_CACHE", str(tmp_path / "cache"))
    _, out, _ = survey
    xyz = load_points(out, cache=False).xyz()
    campaign = open_campaign(out)
    overview = read_overview(campaign, CAP)
    presets = campaign_presets(overview, N)
    settings = MapSettings(cell_size=presets[-1])
    server, app, loaded = _app(campaign, overview, settings)
    try:
        assert app.wait_idle(300)
        from rough_viewer.app.features.crop import CropFeature, crop_text

        feature = app.feature(CropFeature)
        lo, hi = xyz.min(axis=0), xyz.max(axis=0)
        box = CropBox(tuple(lo + 0.2 * (hi - lo)), tuple(lo + [0.6, 0.7, 1.0] * (hi - lo)))
        app.submit(CropJob(feature, box))
        assert app.wait_idle(300)
        assert not app.host.errors, app.host.errors
        shown = app.session.shown.loaded
        assert isinstance(shown, CampaignCrop) and shown.uncropped is loaded
        assert not shown.file_rows  # a LAS export writes its points, not the file's rows
        want = xyz[np.all((xyz >= box.lo) & (xyz <= box.hi), axis=1)]
        assert overview.n < want.shape[0] < N
        np.testing.assert_array_equal(_sorted_rows(shown.cloud.xyz()), _sorted_rows(want))
        assert f"{want.shape[0]:,} of {N:,} points" in crop_text(shown)
        assert_same_cells(app.session.shown.result,
                          grid_roughness(shown.cloud, settings.cell_size, engine="numpy"),
                          rtol=1e-12)
        assert app.session.shown.result.n_points.sum() == want.shape[0]
        # a selection inside the crop keeps exactly its points
        inner = shown.cloud.x < np.median(shown.cloud.x)
        exact = shown.cropped_exact(inner)
        assert isinstance(exact, CampaignCrop) and exact.uncropped is loaded
        assert exact.cloud.n == int(inner.sum()) and exact.crop_exact
        # undo: the campaign again
        app.submit(CropJob(feature, None))
        assert app.wait_idle(300)
        assert app.session.shown.loaded is loaded
        # too many points: one line, the campaign stays shown
        monkeypatch.setattr("rough_viewer.app.campaign.CROP_POINTS", 1_000)
        app.submit(CropJob(feature, box))
        assert app.wait_idle(300)
        assert app.session.shown.loaded is loaded
        said = [str(e) for e in app.host.errors]
        assert said and "the crop needs more than 1,000 points" in said[-1], said
    finally:
        app.stop()
        server.stop()


def test_sets_on_a_campaign_say_their_planes_are_the_overviews(survey, tmp_path, monkeypatch):
    """Show sets on a campaign: the status says the planes, joints, spacing and
    joint roughness are fitted to the overview's points, with the counts."""
    from rough_viewer.app.features.sets import SetsFeature

    monkeypatch.setenv("ROUGH_VIEWER_CACHE", str(tmp_path / "cache"))
    _, out, _ = survey
    campaign = open_campaign(out)
    overview = read_overview(campaign, CAP)
    presets = campaign_presets(overview, N)
    server, app, _ = _app(campaign, overview, MapSettings(cell_size=presets[0]))
    try:
        assert app.wait_idle(300)
        f = app.feature(SetsFeature)
        f.on.value = True
        assert app.wait_idle(300)
        text = f.status.content
        assert f"fitted to the overview's {overview.n:,} of the file's {N:,} points" in text
    finally:
        app.stop()
        server.stop()
