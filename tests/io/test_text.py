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
