"""E57: scans written by pye57, each with its pose, read back into the file's frame."""

from __future__ import annotations

import numpy as np
import pytest

pye57 = pytest.importorskip("pye57")

from rough_viewer.io import load_points  # noqa: E402
from rough_viewer.vocabulary import InputError  # noqa: E402
from tests.helpers import rough_surface  # noqa: E402


def _rot(wxyz):
    """Rotation matrix of a unit quaternion, written out independently of the reader
    (as the product of the quaternion sandwich q v q*)."""
    w, x, y, z = wxyz
    q = np.array([w, x, y, z]) / np.linalg.norm(wxyz)

    def mul(a, b):
        return np.array([
            a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
            a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
            a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
            a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
        ])

    conj = q * np.array([1, -1, -1, -1])
    return np.column_stack([mul(mul(q, np.r_[0.0, e]), conj)[1:] for e in np.eye(3)])


POSES = [
    (np.array([np.cos(0.4), 0.0, 0.0, np.sin(0.4)]), np.array([12.5, -3.0, 1.5])),
    (np.array([0.9, 0.1, -0.3, 0.2]), np.array([-40.0, 7.25, 2.0])),
]


def test_two_posed_scans_equal_the_same_points_as_npy(tmp_path):
    path = tmp_path / "two.e57"
    writer = pye57.E57(str(path), mode="w")
    expected, inten = [], []
    for k, (q, t) in enumerate(POSES):
        local = rough_surface(3000 + 500 * k, seed=k, size=6.0)
        local = local.astype(np.float32).astype(np.float64)  # pye57 stores single precision
        i = np.linspace(0.0, 1.0, local.shape[0], dtype=np.float32)
        writer.write_scan_raw({"cartesianX": local[:, 0], "cartesianY": local[:, 1],
                               "cartesianZ": local[:, 2], "intensity": i},
                              rotation=q / np.linalg.norm(q), translation=t)
        expected.append(local @ _rot(q).T + t)
        inten.append(i)
    writer.close()
    np.save(tmp_path / "same.npy", np.concatenate(expected))
    got = load_points(path)
    ref = load_points(tmp_path / "same.npy")
    np.testing.assert_allclose(got.xyz(), ref.xyz(), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(got.intensity, np.concatenate(inten))
    np.testing.assert_array_equal(np.bincount(got.scan_index), [3000, 3500])
    np.testing.assert_array_equal(got.scanner_positions, np.array([t for _, t in POSES]))
    assert got.source_unit == "m"
    part = got.subset(got.scan_index == 1)
    assert part.n == 3500 and part.intensity.shape == (3500,)
    np.testing.assert_allclose(part.xyz(), expected[1], atol=1e-12)


def test_not_an_e57_is_one_line_error(tmp_path):
    path = tmp_path / "junk.e57"
    path.write_bytes(b"ASTM-E57" + b"\0" * 100)
    with pytest.raises(InputError) as exc:
        load_points(path)
    assert "junk.e57" in str(exc.value) and "\n" not in str(exc.value)


def _spherical_only(path, n: int = 500) -> None:
    """An E57 whose one scan stores range, azimuth and elevation only (written with
    libE57Format's own nodes, as some scanner software does)."""
    lib = pye57.libe57
    e57 = pye57.E57(str(path), mode="w")
    img = e57.image_file
    scan = lib.StructureNode(img)
    scan.set("guid", lib.StringNode(img, "{00000000-0000-0000-0000-000000000001}"))
    proto = lib.StructureNode(img)
    names = ("sphericalRange", "sphericalAzimuth", "sphericalElevation")
    for name in names:
        proto.set(name, lib.FloatNode(img, 0.0, lib.E57_DOUBLE, -10.0, 100.0))
    points = lib.CompressedVectorNode(img, proto, lib.VectorNode(img, True))
    scan.set("points", points)
    e57.data3d.append(scan)
    arrays, buffers = e57.make_buffers(list(names), n)
    rng = np.random.default_rng(0)
    arrays["sphericalRange"][:] = rng.uniform(5.0, 20.0, n)
    arrays["sphericalAzimuth"][:] = rng.uniform(-1.0, 1.0, n)
    arrays["sphericalElevation"][:] = rng.uniform(-0.3, 0.3, n)
    writer = points.writer(buffers)
    writer.write(n)
    writer.close()
    e57.close()


def test_e57_without_cartesian_coordinates_is_one_line_error(tmp_path):
    path = tmp_path / "spherical.e57"
    _spherical_only(path)
    assert "sphericalRange" in pye57.E57(str(path)).get_header(0).point_fields
    with pytest.raises(InputError) as exc:
        load_points(path)
    text = str(exc.value)
    assert "no Cartesian coordinates" in text and "spherical.e57" in text and "\n" not in text
