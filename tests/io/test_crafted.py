"""Every crafted file of issue 21 ends in one line naming the file and exit status 2,
through the command line (the files are made here, in a temporary folder)."""

from __future__ import annotations

import errno
import json
import os
import signal

import numpy as np
import pytest

from rough_viewer.cli import main
from rough_viewer.cli._inputs import expand_inputs
from rough_viewer.io import load_points
from rough_viewer.io.cloud import PointCloud
from rough_viewer.io.formats.las import write_las
from rough_viewer.io.sandbox import isolate
from rough_viewer.vocabulary import InputError
from tests.io import crafted

needs_isolation = pytest.mark.skipif(not isolate.available(), reason="isolation needs Linux")


def _compute(path, tmp_path, capsys, *extra: str) -> str:
    """``compute PATH`` ; its one error line (exit 2 asserted)."""
    out = tmp_path / "cells.csv"
    status = main(["compute", str(path), "--grid", "0.5", "--out", str(out), *extra])
    err = capsys.readouterr().err.strip()
    assert status == 2, err
    assert len(err.splitlines()) == 1 and err.startswith("rough-viewer: error: "), err
    assert str(path) in err
    assert not out.exists() and not [f for f in tmp_path.iterdir() if ".part" in f.name]
    return err


@needs_isolation
def test_a_laz_chunk_of_0xff_is_a_crash_in_the_child(tmp_path, capsys):
    err = _compute(crafted.laz_ff_chunk(tmp_path / "ff.laz"), tmp_path, capsys)
    assert "the LAZ reader crashed (signal 11, SIGSEGV)" in err and "damaged or not LAZ" in err


@needs_isolation
@pytest.mark.parametrize("make", [crafted.laz_huge_chunk_table, crafted.laz_huge_layer])
def test_a_laz_asking_for_gigabytes_stops_at_its_memory_limit(tmp_path, capsys, make):
    """0xFFFFFFFF chunks (64 GiB in lazrs) or a 4 GiB layer (4.2 GB for a 1 KB file)."""
    err = _compute(make(tmp_path / "big.laz"), tmp_path, capsys)
    assert "the LAZ reader went past its memory limit of" in err and "crafted" in err


@needs_isolation
def test_an_e57_nested_160000_levels_is_stopped(tmp_path, capsys, monkeypatch):
    """libE57Format is busy for about a minute, then crashes: the time limit stops it."""
    monkeypatch.setenv("ROUGH_VIEWER_READ_SECONDS", "2")
    path = crafted.nested_e57(tmp_path / "pump.e57")
    assert path.stat().st_size > 3_800_000
    err = _compute(path, tmp_path, capsys)
    assert "the E57 reader took longer than 2 s" in err or "the E57 reader crashed" in err


def test_an_e57_error_while_reading_its_scans_is_one_line(tmp_path, capsys):
    err = _compute(crafted.e57_without_data(tmp_path / "empty.e57"), tmp_path, capsys)
    assert "cannot read" in err and "ErrorPathUndefined" in err


def test_a_lazrs_panic_is_one_line(tmp_path, capsys):
    """A LasZip record of 0 items: pyo3's PanicException is a BaseException."""
    err = _compute(crafted.laz_zero_items(tmp_path / "zero.laz"), tmp_path, capsys)
    assert "the decoder failed (attempt to calculate the remainder with a divisor of zero)" in err


def test_a_decompression_bomb_is_refused_before_decoding_unless_allowed(tmp_path, capsys):
    bomb = crafted.laz_declaring(tmp_path / "bomb.laz", 50_000_000)
    err = _compute(bomb, tmp_path, capsys)
    assert "declares 50,000,000 points in" in err and "decompression bomb" in err
    assert "raise the limit with --max-points 50000000" in err
    # a genuine cloud as small: 2.5 M identical points in 20 KB, read once allowed
    flat = crafted.constant_laz(tmp_path / "flat.laz", 2_500_000)
    assert flat.stat().st_size < 100_000
    with pytest.raises(InputError, match="decompression bomb"):
        load_points(flat)
    cloud = load_points(flat, max_points=3_000_000, cache=False)
    assert cloud.n == 2_500_000 and float(np.abs(cloud.x).max()) == 0.0


@pytest.mark.parametrize("make, message", [
    (lambda p: np.savez(p.with_suffix(".npz"), a=np.zeros((4, 3))) or
     os.replace(p.with_suffix(".npz"), p), "is a NumPy .npz archive"),
    (lambda p: np.save(p, np.zeros((4, 2), dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])),
     "holds a structured array of shape (4, 2)"),
    (lambda p: np.save(p, np.zeros((4, 3)).ravel()[:10].reshape(5, 2)),
     "expected an (N, 3) numeric array"),
])
def test_disguised_and_structured_npy_files_are_one_line(tmp_path, capsys, make, message):
    path = tmp_path / "points.npy"
    make(path)
    assert message in _compute(path, tmp_path, capsys)


def test_a_truncated_npy_is_refused_from_its_header(tmp_path, capsys):
    path = tmp_path / "cut.npy"
    np.save(path, np.zeros((1000, 3)))
    path.write_bytes(path.read_bytes()[:2000])
    assert "is truncated: its header declares 24,000 bytes" in _compute(path, tmp_path, capsys)


def test_huge_coordinates_are_one_line(tmp_path, capsys):
    path = tmp_path / "far.xyz"
    path.write_text("0 0 0\n1e290 0 0\n0 1e290 0\n1e290 1e290 1\n")
    err = _compute(path, tmp_path, capsys)
    assert "reach 1e+290 m in x" in err and "LinAlgError" not in err


def test_ply_counts_below_zero_and_long_header_lines_are_one_line(tmp_path, capsys):
    body = "0 0 0\n1 0 0\n0 1 0\n1 1 1\n3 0 1 2\n"
    path = tmp_path / "neg.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex -1\nproperty float x\n"
                    "property float y\nproperty float z\nelement face 1\n"
                    "property list uchar int vertex_indices\nend_header\n" + body)
    assert "declares -1 records" in _compute(path, tmp_path, capsys)
    path = tmp_path / "comment.ply"
    path.write_text("ply\nformat ascii 1.0\ncomment " + "x " * 40_000 + "\nelement vertex 4\n"
                    "property float x\nproperty float y\nproperty float z\nend_header\n" + body)
    assert "a line longer than 65,536 bytes" in _compute(path, tmp_path, capsys)


def test_a_csv_with_a_bom_keeps_its_first_point(tmp_path):
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbf1.5,2,3\n4,5,6\n7,8,9\n")
    cloud = load_points(path)
    np.testing.assert_array_equal(cloud.x, [1.5, 4.0, 7.0])


def test_demo_generate_onto_a_full_disk_is_one_line(tmp_path, capsys, monkeypatch):
    """ENOSPC at the write call, wrapped by the LAZ writer in its own error type."""
    import laspy

    def full(self, destination, *args, **kwargs):
        with open(destination, "wb") as fh:
            fh.write(b"LASF" + b"\0" * 1000)
        raise RuntimeError("LazrsError: IoError: No space left on device (os error 28)")

    monkeypatch.setattr(laspy.LasData, "write", full)
    out = tmp_path / "board.laz"
    status = main(["demo", "generate", "board", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert status == 2 and err == f"rough-viewer: error: cannot write {out}: no space left on device"
    assert list(tmp_path.iterdir()) == []


def test_an_os_error_of_a_full_disk_is_one_line(tmp_path):
    from rough_viewer.io.output import write_atomic

    def write(fh):
        fh.write("x")
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(InputError, match="no space left on device"):
        write_atomic(tmp_path / "t.csv", write)
    assert list(tmp_path.iterdir()) == []


def test_view_with_a_400_digit_integer_is_one_line(tmp_path, capsys):
    view = tmp_path / "scan.view.json"
    view.write_text(json.dumps({"format": "rough-viewer view", "version": 1})[:-1]
                    + ', "seed": ' + "9" * 400 + "}")
    status = main(["serve", "--view", str(view), "--no-block"])
    err = capsys.readouterr().err.strip()
    assert status == 2 and len(err.splitlines()) == 1
    assert "not valid JSON: an integer of 400 digits" in err


def test_globs_do_not_follow_folder_symlinks(tmp_path, monkeypatch):
    scans = tmp_path / "scans"
    (scans / "a").mkdir(parents=True)
    for name in ("scans/one.xyz", "scans/a/two.xyz"):
        (tmp_path / name).write_text("0 0 0\n1 0 0\n0 1 0\n")
    (scans / "a" / "up").symlink_to("..")           # one link back up ...
    (scans / "a" / "top").symlink_to(tmp_path)      # ... and a second: Python's glob never ended
    (scans / "link.xyz").symlink_to(scans / "one.xyz")  # a link to a file is followed
    (scans / ".hidden.xyz").write_text("0 0 0\n")
    monkeypatch.chdir(tmp_path)
    found = [str(p) for p in expand_inputs(["scans/**/*.xyz"])]
    assert found == ["scans/a/two.xyz", "scans/link.xyz", "scans/one.xyz"]
    assert [str(p) for p in expand_inputs(["scans/*/t*.xyz"])] == ["scans/a/two.xyz"]
    assert [str(p) for p in expand_inputs([f"{scans}/**"])] == [
        f"{scans}/a/two.xyz", f"{scans}/link.xyz", f"{scans}/one.xyz"]


def test_sigterm_cleans_up_like_ctrl_c(tmp_path, capsys, monkeypatch):
    """SIGTERM arriving while compute writes its outputs: no output, no hidden .part."""
    import rough_viewer.io.table as table

    src = tmp_path / "face.xyz"
    rng = np.random.default_rng(0)
    np.savetxt(src, np.column_stack([rng.uniform(0, 2, (2000, 2)), rng.normal(0, 1e-3, 2000)]))
    real = table.write_atomic

    def interrupted(path, write, **kwargs):
        def body(fh):
            write(fh)
            os.kill(os.getpid(), signal.SIGTERM)
        real(path, body, **kwargs)

    monkeypatch.setattr(table, "write_atomic", interrupted)
    status = main(["compute", str(src), "--grid", "0.5", "--out", str(tmp_path / "cells.csv"),
                   "--summary-json", str(tmp_path / "summary.json")])
    assert status == 143 and "terminated" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["face.xyz"]
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL


def test_a_second_run_without_force_never_replaces_the_first(tmp_path):
    """Both runs pass the 'exists' check; the slower one refuses at the end."""
    from rough_viewer.io.output import check_output_path, write_atomic

    out = tmp_path / "cells.csv"
    for _run in ("first", "second"):
        check_output_path(out, force=False)
    write_atomic(out, lambda fh: fh.write("first\n"))
    with pytest.raises(InputError, match="output file exists: .*another run wrote it"):
        write_atomic(out, lambda fh: fh.write("second\n"))
    assert out.read_text() == "first\n" and sorted(p.name for p in tmp_path.iterdir()) == ["cells.csv"]
    check_output_path(out, force=True)
    write_atomic(out, lambda fh: fh.write("forced\n"))
    assert out.read_text() == "forced\n"


def test_the_las_output_of_two_runs_is_exclusive_too(tmp_path):
    from rough_viewer.io.output import check_output_path, write_path_atomic

    out = tmp_path / "out.laz"
    cloud = PointCloud.from_xyz(np.random.default_rng(1).uniform(0, 1, (50, 3)))
    check_output_path(out, force=False)
    check_output_path(out, force=False)
    write_path_atomic(out, lambda tmp: write_las(tmp, cloud))
    first = out.read_bytes()
    with pytest.raises(InputError, match="output file exists"):
        write_path_atomic(out, lambda tmp: write_las(tmp, cloud, scale=1e-3))
    assert out.read_bytes() == first


@needs_isolation
def test_extra_dimensions_and_point_source_ids_decode_in_the_child_too(tmp_path, capsys):
    """bias normalise --truth-dim and --scanners decode the file again: isolated too."""
    from rough_viewer.io import read_las_extra
    from rough_viewer.scanner.positions import point_source_ids

    bad = crafted.laz_ff_chunk(tmp_path / "ff.laz")
    with pytest.raises(InputError, match="the LAS/LAZ reader crashed .* on .*ff.laz"):
        read_las_extra(bad, "truth")
    with pytest.raises(InputError, match="the LAS/LAZ reader crashed .* on .*ff.laz"):
        point_source_ids(bad)
    good = tmp_path / "good.laz"
    cloud = PointCloud.from_xyz(np.random.default_rng(2).uniform(0, 1, (300, 3)))
    write_las(good, cloud, extra={"truth": (np.arange(300) % 200).astype(np.uint8)})
    np.testing.assert_array_equal(read_las_extra(good, "truth"), np.arange(300) % 200)
    assert point_source_ids(good).tolist() == [0] * 300


def test_a_mesh_declaring_4e9_faces_is_refused_before_any_allocation(tmp_path):
    """plyfile would allocate 52 GB for the faces of a 200-byte PLY (directions, report);
    the reader checks the count against the bytes the file holds (in the child, where
    reads are isolated, and without it alike)."""
    import struct

    from rough_viewer.io.formats.mesh import load_mesh

    path = tmp_path / "faces.ply"
    path.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
                     b"property float y\nproperty float z\nelement face 4000000000\n"
                     b"property list uchar int vertex_indices\nend_header\n"
                     + struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + bytes([3])
                     + struct.pack("<3i", 0, 1, 2))
    with pytest.raises(InputError, match="declares 4,000,000,000 face records but the file "
                                         "holds at most 13"):
        load_mesh(path)
