"""The data folder and reading files within memory, with messages fit for a browser."""

from __future__ import annotations

import numpy as np
import pytest

import rough_viewer.memory as memory
from rough_viewer.app.files import DataFolder, read_cloud, read_estimate
from rough_viewer.io.estimates import COSTS
from rough_viewer.memory import format_bytes
from rough_viewer.vocabulary import InputError


@pytest.fixture
def folder(tmp_path):
    data = tmp_path / "data"
    (data / "sub").mkdir(parents=True)
    np.save(data / "sub" / "a.npy", np.random.default_rng(0).uniform(0, 1, (100, 3)))
    (tmp_path / "secret.xyz").write_text("1 2 3\n4 5 6\n7 8 9\n")
    (data / "escape.xyz").symlink_to(tmp_path / "secret.xyz")
    return DataFolder.of(data)


def test_paths_resolve_inside_the_folder_only(folder, tmp_path):
    assert folder.resolve("sub/a.npy") == folder.root / "sub" / "a.npy"
    assert folder.resolve(f"  {folder.root}/sub/a.npy ") == folder.root / "sub" / "a.npy"
    assert folder.shown(folder.root / "sub" / "a.npy") == "sub/a.npy"
    for typed in ("../secret.xyz", str(tmp_path / "secret.xyz"), "escape.xyz",
                  "sub/../../secret.xyz", "~/x.las", "/etc/passwd.xyz"):
        with pytest.raises(InputError, match="outside the data folder") as exc:
            folder.resolve(typed)
        assert str(folder.root) not in str(exc.value)
    for typed, message in (("", "no file path"), ("sub/missing.las", "file not found: sub/"),
                           ("sub/a.exe", "unknown file type"), ("a\x00.las", "NUL")):
        with pytest.raises(InputError, match=message):
            folder.resolve(typed)
    with pytest.raises(InputError, match="not a folder"):
        DataFolder.of(tmp_path / "nope")


def test_reading_checks_memory_and_hides_paths_and_content(folder, monkeypatch):
    bad = folder.root / "bad.xyz"
    bad.write_text("x y z\n1 2 password123\n")
    with pytest.raises(InputError) as exc:
        read_cloud(bad, "bad.xyz")
    text = str(exc.value)
    assert "bad.xyz" in text and "password123" not in text and str(folder.root) not in text
    big = folder.root / "big.xyz"
    big.write_text("0 0 0\n" * 10_000)
    size = big.stat().st_size
    cost = COSTS["text"]
    assert read_estimate(big) == cost.per_byte * size + cost.per_point * (size // 6)
    monkeypatch.setattr(memory, "available_bytes", lambda: 100_000.0)
    with pytest.raises(InputError, match="reading big.xyz needs about "
                       f"{format_bytes(read_estimate(big))}"):
        read_cloud(big, "big.xyz")
    monkeypatch.undo()
    assert read_cloud(big, "big.xyz").n == 10_000
