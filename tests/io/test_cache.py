"""The decode cache cannot lie: every way an entry can be damaged is found, the entry
dropped with a notice and the file decoded again to the right points; an in-place
header edit misses; the cache keeps within its cap and its disk (issue 21)."""

from __future__ import annotations

import errno
import json
import os
import shutil
from collections import namedtuple

import numpy as np
import pytest

from rough_viewer.io import cache, load_points
from rough_viewer.io.formats.las import write_las
from tests.helpers import face_cloud


@pytest.fixture
def laz(tmp_path, monkeypatch):
    """A LAZ file of 3,000 points, an empty cache of its own, and its true points."""
    monkeypatch.setenv("ROUGH_VIEWER_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("ROUGH_VIEWER_CACHE_MB", raising=False)
    path = tmp_path / "face.laz"
    write_las(path, face_cloud(3000))
    truth = load_points(path, cache=False)
    return path, truth


def _entry(path):
    return cache.cache_dir() / cache.cache_key(path)


def _same(a, b) -> None:
    for c in "xyz":
        np.testing.assert_array_equal(getattr(a, c), getattr(b, c))
    np.testing.assert_array_equal(a.intensity, b.intensity)


def _zero_column(folder):
    (folder / "y.npy").write_bytes(b"")


def _truncate_column(folder):
    data = (folder / "z.npy").read_bytes()
    (folder / "z.npy").write_bytes(data[:-8])


def _garbage_meta(folder):
    (folder / "meta.json").write_text("{not json")


def _no_meta(folder):
    (folder / "meta.json").unlink()


def _unequal_lengths(folder):
    x = np.load(folder / "x.npy")
    np.save(folder / "x.npy", x[:-1])


def _flipped_byte(folder):
    data = bytearray((folder / "x.npy").read_bytes())
    data[-100] ^= 0x01
    (folder / "x.npy").write_bytes(bytes(data))


def _wrong_type(folder):
    np.save(folder / "intensity.npy", np.load(folder / "intensity.npy").astype(np.int64))


def _meta_lies(folder):
    meta = json.loads((folder / "meta.json").read_text())
    meta["n"] = 10
    (folder / "meta.json").write_text(json.dumps(meta))


@pytest.mark.parametrize("damage, why", [
    (_zero_column, "y.npy is not a NumPy file"),
    (_truncate_column, "z.npy is"),
    (_garbage_meta, "meta.json is not valid JSON"),
    (_no_meta, "meta.json is missing"),
    (_unequal_lengths, "x.npy holds"),
    (_flipped_byte, "x.npy does not match its checksum"),
    (_wrong_type, "intensity.npy holds int64"),
    (_meta_lies, "x.npy holds float64 (3000,), not float64 (10,)"),
])
def test_a_damaged_entry_is_dropped_and_the_file_decoded_again(laz, damage, why):
    path, truth = laz
    first = load_points(path)
    _same(first, truth)
    folder = _entry(path)
    assert (folder / "meta.json").exists()
    assert load_points(path).warnings == ()  # a clean hit
    damage(folder)
    again = load_points(path)
    _same(again, truth)
    notes = [w for w in again.warnings if "decode cache" in w]
    assert len(notes) == 1 and why in notes[0] and str(path) in notes[0]
    assert "dropped and the file decoded again" in notes[0]
    hit = cache.cache_lookup(path)  # written anew, whole
    assert hit.notice is None and hit.cloud is not None and hit.cloud.n == truth.n


def test_an_in_place_header_edit_that_kept_the_time_misses(laz):
    """The x offset (header byte 155) moved by 1000 m, the mtime put back."""
    path, truth = laz
    load_points(path)
    st = path.stat()
    data = bytearray(path.read_bytes())
    offset = np.frombuffer(bytes(data[155:163]), dtype="<f8")[0]
    data[155:163] = np.array([offset + 1000.0]).tobytes()
    path.write_bytes(bytes(data))
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert path.stat().st_size == st.st_size and path.stat().st_mtime_ns == st.st_mtime_ns
    moved = load_points(path)
    np.testing.assert_allclose(moved.x, truth.x + 1000.0)


def test_slices_of_a_damaged_entry_are_refused(laz):
    path, truth = laz
    load_points(path)
    assert cache.cached_points(path) == truth.n
    cols = cache.cache_read_slice(path, 100, 200)
    assert cols is not None
    np.testing.assert_array_equal(cols[0], truth.x[100:200])
    _flipped_byte(_entry(path))
    assert cache.cache_read_slice(path, 100, 200) is None
    assert not _entry(path).exists()


def test_least_recently_used_entries_go_first(tmp_path, monkeypatch):
    monkeypatch.setenv("ROUGH_VIEWER_CACHE", str(tmp_path / "cache"))
    paths = []
    for k in range(3):
        p = tmp_path / f"s{k}.laz"
        write_las(p, face_cloud(20_000, seed=k))
        paths.append(p)
    entry = 20_000 * (24 + 2)
    monkeypatch.setenv("ROUGH_VIEWER_CACHE_MB", str(2.5 * entry / 1e6))  # room for two
    load_points(paths[0])
    load_points(paths[1])
    os.utime(_entry(paths[1]) / "meta.json", (1, 1))  # s1 used long ago ...
    load_points(paths[0])                            # ... s0 just now
    load_points(paths[2])
    assert [cache.cached_points(p) for p in paths] == [20_000, None, 20_000]
    monkeypatch.setenv("ROUGH_VIEWER_CACHE_MB", "0")  # off
    shutil.rmtree(tmp_path / "cache")
    load_points(paths[0])
    assert cache.cached_points(paths[0]) is None


def test_no_entry_on_a_disk_without_room_and_nothing_left_behind(laz, monkeypatch):
    path, truth = laz
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(cache.shutil, "disk_usage",
                        lambda _p: usage(10 << 30, (10 << 30) - (100 << 20), 100 << 20))
    _same(load_points(path), truth)  # 100 MiB free < the 1 GiB reserve
    assert cache.cached_points(path) is None
    assert [p.name for p in cache.cache_dir().iterdir()] == []


def test_a_full_disk_while_writing_leaves_no_part_folder(laz, monkeypatch):
    path, truth = laz
    real = cache._Column.append

    def full(self, values):
        real(self, values[:10])
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(cache._Column, "append", full)
    _same(load_points(path), truth)
    assert list(cache.cache_dir().iterdir()) == []


def test_part_folders_of_dead_processes_are_swept(laz):
    path, _ = laz
    root = cache.cache_dir()
    root.mkdir(parents=True, exist_ok=True)
    dead = root / ".part-999999999-abc"
    live = root / f".part-{os.getpid()}-def"
    dead.mkdir()
    live.mkdir()
    load_points(path)
    assert not dead.exists() and live.exists()


def test_entries_are_fsynced_before_they_are_published(laz, monkeypatch):
    path, _ = laz
    synced: list[int] = []
    real = os.fsync
    monkeypatch.setattr(cache.os, "fsync", lambda fd: (synced.append(fd), real(fd))[1])
    renamed: list[tuple[int, str]] = []
    real_rename = os.rename
    monkeypatch.setattr(cache.os, "rename",
                        lambda a, b: (renamed.append((len(synced), str(b))), real_rename(a, b))[1])
    load_points(path)
    # x, y, z, intensity, meta.json and the folder before the rename; the root after
    assert renamed and renamed[0][0] == 6 and len(synced) == 7
