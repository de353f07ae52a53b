"""Crop: the box's mask against brute force, every per-point field kept, and a LAS/LAZ
copy of the kept points only with every dimension byte for byte."""

from __future__ import annotations

import laspy
import numpy as np
import pytest

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.table import point_fields
from rough_viewer.io import PointCloud, load_points
from rough_viewer.io.crop import CropBox, crop_cloud, crop_mask
from rough_viewer.io.formats.las_out import write_las_fields
from rough_viewer.vocabulary import InputError
from tests.io.test_las_out import make_pf3  # LAS 1.2 format 3, every kind of dimension

OFFSET = np.array([238_000.0, 3_765_000.0, 250.0])  # make_pf3's


def brute_force_inside(xyz: np.ndarray, lo, hi) -> np.ndarray:
    return np.array([all(lo[a] <= p[a] <= hi[a] for a in range(3)) for p in xyz.tolist()])


def test_mask_matches_brute_force_and_remove_is_its_complement():
    rng = np.random.default_rng(0)
    xyz = rng.uniform(-1.0, 1.0, (3_000, 3))
    xyz[:10] = [0.25, -0.5, 0.0]  # points on the box's faces are inside
    box = CropBox((-0.5, -0.5, -0.2), (0.25, 0.6, 0.0))
    inside = brute_force_inside(xyz, box.lo, box.hi)
    assert inside[:10].all() and 0 < inside.sum() < 3_000
    assert np.array_equal(crop_mask(xyz, box), inside)
    assert np.array_equal(crop_mask(xyz, CropBox(box.lo, box.hi, "remove")), ~inside)


def test_cropped_cloud_keeps_every_field():
    rng = np.random.default_rng(1)
    n = 500
    cloud = PointCloud.from_xyz(rng.uniform(0, 1, (n, 3)), intensity=rng.integers(0, 999, n),
                                rgb=rng.integers(0, 255, (n, 3), dtype=np.uint8),
                                scan_index=rng.integers(0, 3, n).astype(np.int32),
                                scanner_positions=np.zeros((3, 3)), source="scan.e57")
    cropped = crop_cloud(cloud, CropBox((0.2, 0.2, 0.2), (0.9, 0.9, 0.9)))
    m = cropped.mask
    assert cropped.kept == int(m.sum()) and cropped.total == n
    got = cropped.cloud
    for name in ("x", "y", "z", "intensity", "rgb", "scan_index"):
        assert np.array_equal(getattr(got, name), getattr(cloud, name)[m]), name
    assert got.scanner_positions is cloud.scanner_positions and got.source == "scan.e57"


def test_bad_boxes_and_empty_crops_are_refused():
    with pytest.raises(InputError, match="x minimum 2 is above its maximum 1"):
        CropBox((2.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    with pytest.raises(InputError, match="finite"):
        CropBox((0.0, 0.0, float("nan")), (1.0, 1.0, 1.0))
    with pytest.raises(InputError, match="keep or remove"):
        CropBox((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), "cut")  # type: ignore[arg-type]
    cloud = PointCloud.from_xyz(np.random.default_rng(2).uniform(0, 1, (100, 3)), source="a.xyz")
    with pytest.raises(InputError, match=r"the crop keeps 0 of the 100 points of a\.xyz"):
        crop_cloud(cloud, CropBox((5.0, 5.0, 5.0), (6.0, 6.0, 6.0)))


def test_box_around_a_selection_and_in_another_unit():
    xyz = np.array([[0.0, 0, 0], [1, 2, 3], [4, 5, 6]])
    box = CropBox.around(xyz, np.array([False, True, True]), mode="remove")
    assert box == CropBox((1.0, 2.0, 3.0), (4.0, 5.0, 6.0), "remove")
    assert box.scaled(0.001).hi == pytest.approx((0.004, 0.005, 0.006))
    assert "removed the points inside the box (1, 2, 3) to (4, 5, 6) m" in box.describe()


@pytest.mark.parametrize("suffix", [".las", ".laz"])
def test_las_copy_of_a_crop_holds_the_kept_points_with_every_dimension(tmp_path, suffix):
    src = tmp_path / "scan.las"
    make_pf3(src, n=4000)
    cloud = load_points(src, cache=False)
    box = CropBox(tuple(OFFSET + [0.5, 0.7, -1.0]), tuple(OFFSET + [2.2, 2.5, 1.0]))
    cropped = crop_cloud(cloud, box)
    result = grid_roughness(cropped.cloud, 0.5)
    fields = point_fields(result)
    out = tmp_path / f"crop{suffix}"
    write_las_fields(out, cropped.cloud, fields, keep=cropped.mask, chunk_points=700)
    original = laspy.read(str(src))
    written = laspy.read(str(out))
    rows = np.flatnonzero(cropped.mask)
    assert len(written.points) == cropped.kept == rows.shape[0] < len(original.points)
    for dim in original.point_format.dimension_names:
        assert np.array_equal(np.asarray(written[dim]), np.asarray(original[dim])[rows]), dim
    for f, values in zip(fields.fields, fields.gather(0, cropped.kept), strict=True):
        assert np.array_equal(np.asarray(written[f.name]), values, equal_nan=True), f.name
    assert [v.record_data for v in written.header.vlrs if v.user_id == "NIIRS10"] == [
        b"\x01\x02\x03\x04\x05"]
    assert np.allclose(written.header.mins, cropped.cloud.bounds()[0], atol=1e-6)
    assert np.allclose(written.header.maxs, cropped.cloud.bounds()[1], atol=1e-6)


def test_las_copy_of_a_crop_without_its_mask_says_so(tmp_path):
    src = tmp_path / "scan.las"
    make_pf3(src, n=500)
    cropped = crop_cloud(load_points(src, cache=False),
                         CropBox(tuple(OFFSET), tuple(OFFSET + [1.5, 3.0, 1.0])))
    fields = point_fields(grid_roughness(cropped.cloud, 0.5))
    with pytest.raises(InputError, match="a cropped cloud needs its crop mask"):
        write_las_fields(tmp_path / "out.las", cropped.cloud, fields)
    with pytest.raises(InputError, match="the crop keeps 0 points but the cropped cloud has"):
        write_las_fields(tmp_path / "out.las", cropped.cloud, fields,
                         keep=np.zeros_like(cropped.mask))
    assert not (tmp_path / "out.las").exists()
