"""Text point files: which first line is a header, and NaN rows counted right."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.io import load_points
from rough_viewer.vocabulary import InputError

ROWS = "1 0 0\n0 1 0\n1 1 0.5\n0.5 0.5 0.25\n"


@pytest.mark.parametrize("first, kept, dropped", [
    ("0 0 nan\n", None, 1),        # a point with a missing z: data, dropped and counted
    ("NaN,0,0\n", None, 1),        # any case, comma separated
    ("0 -inf 1\n", None, 1),
    ("2 2 2\n", (2.0, 2.0, 2.0), 0),  # plain numbers: data, kept
    ("1e-3 .5 +2\n", (1e-3, 0.5, 2.0), 0),
    ("x y z\n", None, 0),          # words: a header, skipped
    ("X,Y,Z,intensity\n", None, 0),
    ("nanometres y z\n", None, 0),  # a word that starts like a number is still a word
])
def test_first_line_of_numbers_is_data_else_a_header(tmp_path, first, kept, dropped):
    rows = ROWS.replace(" ", ",") if "," in first else ROWS
    path = tmp_path / "cloud.xyz"
    path.write_text(first + rows)
    cloud = load_points(path)
    expected = [[1, 0, 0], [0, 1, 0], [1, 1, 0.5], [0.5, 0.5, 0.25]]
    if kept is not None:
        expected.insert(0, list(kept))
    assert (cloud.n, cloud.dropped_nonfinite) == (len(expected), dropped)
    np.testing.assert_array_equal(np.column_stack([cloud.x, cloud.y, cloud.z]),
                                  np.array(expected, dtype=float))


def test_folder_as_input_says_folder(tmp_path):
    (tmp_path / "scans.laz").mkdir()
    for folder in (tmp_path, tmp_path / "scans.laz"):
        with pytest.raises(InputError) as info:
            load_points(folder)
        assert str(info.value).startswith(f"{folder} is a folder, not a point file")
        assert "unknown file type" not in str(info.value)


EXPECTED = np.array([[1, 0, 0], [0, 1, 0], [1, 1, 0.5], [0.5, 0.5, 0.25]], dtype=float)


@pytest.mark.parametrize("name, text", [
    ("leica.pts", "4\n1 0 0 61014\n0 1 0 61000\n1 1 0.5 60000\n0.5 0.5 0.25 59000\n"),
    ("semi.csv", "X;Y;Z\n1;0;0\n0;1;0\n1;1;0.5\n0.5;0.5;0.25\n"),
    ("semi_nohdr.csv", "1;0;0\n0;1;0\n1;1;0.5\n0.5;0.5;0.25\n"),
    ("comment.csv", "# exported by CloudCompare\nx,y,z,intensity\n1,0,0,5\n0,1,0,5\n"
                    "1,1,0.5,5\n0.5,0.5,0.25,5\n"),
    ("crlf_tabs.txt", "x\ty\tz\r\n1\t0\t0\r\n0\t1\t0\r\n1\t1\t0.5\r\n0.5\t0.5\t0.25\r\n"),
    ("comments_between.xyz", "# a\n\n1 0 0\n# b\n0 1 0\n1 1 0.5\n0.5 0.5 0.25\n"),
])
def test_common_exports_read_as_the_same_points(tmp_path, name, text):
    """Leica .pts (a point count first), semicolon CSV, a comment before the header:
    all were refused or misread ('found 1 column', 'could not convert x,y,z')."""
    path = tmp_path / name
    path.write_bytes(text.encode())
    cloud = load_points(path)
    np.testing.assert_array_equal(np.column_stack([cloud.x, cloud.y, cloud.z]), EXPECTED)


def test_header_only_and_pickled_npy_are_one_line(tmp_path, capfd):
    path = tmp_path / "h.csv"
    path.write_text("x,y,z\n")
    with pytest.raises(InputError, match="no points in .*h.csv"):
        load_points(path)
    assert "UserWarning" not in capfd.readouterr().err  # numpy's warning stays quiet
    fake = tmp_path / "notnpy.npy"
    fake.write_text("hello")
    with pytest.raises(InputError) as info:
        load_points(fake)
    assert "not a NumPy .npy array" in str(info.value) and "unsafely" not in str(info.value)


@pytest.mark.parametrize("layout", ["c", "fortran", "float32", "big-endian", "int16", "wide"])
def test_npy_columns_are_read_straight_from_the_file(tmp_path, monkeypatch, layout):
    """Every plain numeric layout reads into the same float64 columns as np.load gives,
    block by block (blocks made small here), non-finite rows dropped across blocks."""
    import rough_viewer.io.formats.text as text

    monkeypatch.setattr(text, "NPY_BLOCK_ROWS", 1000)
    rng = np.random.default_rng(1)
    arr = rng.normal(size=(4_321, 3 if layout != "wide" else 6)) * 100 + 5e5
    if layout != "int16":
        arr[[5, 2_500], [1, 2]] = [np.nan, np.inf]
    make = {"fortran": np.asfortranarray, "float32": lambda a: a.astype(np.float32),
            "big-endian": lambda a: a.astype(">f8"), "int16": lambda a: (a - 5e5).astype(np.int16)}
    arr = make.get(layout, lambda a: a)(arr)
    np.save(tmp_path / "c.npy", arr)
    cloud = load_points(tmp_path / "c.npy")
    ref = np.load(tmp_path / "c.npy").astype(np.float64)[:, :3]
    ref = ref[np.isfinite(ref).all(axis=1)]
    np.testing.assert_array_equal(np.column_stack([cloud.x, cloud.y, cloud.z]), ref)
    assert cloud.dropped_nonfinite == (0 if layout == "int16" else 2)
    assert all(c.flags.c_contiguous and c.dtype == np.float64 for c in (cloud.x, cloud.y, cloud.z))


def test_truncated_npy_is_one_line(tmp_path):
    np.save(tmp_path / "t.npy", np.ones((1_000, 3)))
    data = (tmp_path / "t.npy").read_bytes()
    (tmp_path / "t.npy").write_bytes(data[:-50])
    with pytest.raises(InputError, match="t.npy"):
        load_points(tmp_path / "t.npy")
