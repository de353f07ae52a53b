"""Output safety (issue 15): nothing overwritten without force, nothing written outside
the chosen folder, no partial file after a failure, one-line errors."""

from __future__ import annotations

import errno
import os

import pytest

from rough_viewer.cli import main
from rough_viewer.io.output import (
    all_or_nothing,
    check_output_path,
    check_outputs,
    path_in_folder,
    write_atomic,
    write_path_atomic,
)
from rough_viewer.vocabulary import InputError


def _names(folder) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_existing_file_needs_force(tmp_path):
    p = tmp_path / "a.csv"
    p.write_text("old")
    with pytest.raises(InputError, match="exists.*--force"):
        check_output_path(p, force=False)
    assert check_output_path(p, force=True) == p


def test_symlink_refused_even_with_force(tmp_path):
    target = tmp_path / "elsewhere.csv"
    target.write_text("precious")
    link = tmp_path / "link.csv"
    link.symlink_to(target)
    dangling = tmp_path / "dangling.csv"
    dangling.symlink_to(tmp_path / "missing.csv")
    for p in (link, dangling):
        with pytest.raises(InputError, match="symbolic link"):
            check_output_path(p, force=True)
    assert target.read_text() == "precious"


def test_device_refused():
    with pytest.raises(InputError, match="not a regular file"):
        check_output_path("/dev/null", force=True)


def test_output_equal_to_input_refused(tmp_path, monkeypatch):
    src = tmp_path / "scan.laz"
    src.write_bytes(b"x")
    hard = tmp_path / "hard.laz"
    os.link(src, hard)
    (tmp_path / "sub").mkdir()
    via_link = tmp_path / "sublink"
    via_link.symlink_to(tmp_path)
    monkeypatch.chdir(tmp_path / "sub")
    for out in (src, "../scan.laz", hard, via_link / "scan.laz"):
        with pytest.raises(InputError, match="is the input file"):
            check_output_path(out, force=True, inputs=[src])


def test_two_outputs_with_one_path_refused(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError, match="two outputs have the same path"):
        check_outputs(["a.csv", tmp_path / "a.csv"], force=True)
    assert [str(p) for p in check_outputs(["a.csv", "b.csv"], force=False)] == ["a.csv", "b.csv"]


def test_names_stay_in_the_folder(tmp_path):
    (tmp_path / "exports").mkdir()
    folder = tmp_path / "exports"
    assert path_in_folder(folder, "map.png") == folder / "map.png"
    for bad in ("../map.png", "/etc/passwd", "..", "", "sub/../../x.png"):
        with pytest.raises(InputError, match="outside the chosen folder"):
            path_in_folder(folder, bad)
    (folder / "out").symlink_to(tmp_path)
    with pytest.raises(InputError, match="outside the chosen folder"):
        path_in_folder(folder, "out/map.png")
    with pytest.raises(InputError, match="outside the chosen folder"):
        check_output_path(tmp_path / "x.csv", force=False, folder=folder)


def test_full_disk_mid_write_leaves_nothing(tmp_path):
    p = tmp_path / "cells.csv"
    p.write_text("the old table")

    def write(fh):
        fh.write("ix,iy\n" * 1000)
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(InputError) as info:
        write_atomic(p, write)
    assert str(info.value) == f"cannot write {p}: no space left on device"
    assert _names(tmp_path) == ["cells.csv"] and p.read_text() == "the old table"


def test_interrupt_mid_write_leaves_nothing(tmp_path):
    def write(fh):
        fh.write("half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_atomic(tmp_path / "x.csv", write)
    assert _names(tmp_path) == []


def test_read_only_folder(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        if os.access(folder, os.W_OK):
            pytest.skip("running as root: a read-only mode does not stop writes")
        with pytest.raises(InputError, match="not writable"):
            check_output_path(folder / "a.csv", force=False)
        with pytest.raises(InputError, match="permission denied"):
            write_atomic(folder / "a.csv", lambda fh: fh.write("x"))
        assert _names(folder) == []
    finally:
        folder.chmod(0o755)


def test_read_only_file_system_error_is_one_line(tmp_path):
    """What a read-only mount says (EROFS), as root sees it too."""
    def write(fh):
        raise OSError(errno.EROFS, "Read-only file system")

    with pytest.raises(InputError, match="read-only file system"):
        write_atomic(tmp_path / "a.csv", write)
    assert _names(tmp_path) == []


def _run(argv, capsys):
    code = main(argv)
    err = capsys.readouterr().err
    return code, err


def test_compute_refusals_are_one_line(tmp_path, capsys):
    import numpy as np

    from tests.helpers import rough_surface

    src = tmp_path / "face.npy"
    np.save(src, rough_surface(500, seed=3, size=2.0))
    base = ["compute", str(src), "--grid", "0.5", "--quiet"]
    cases = {
        "no output": (base, "no output given"),
        "same path": (base + ["--out", str(tmp_path / "a.csv"), "--summary-json",
                              str(tmp_path / "a.csv")], "two outputs have the same path"),
        "input as output": (base + ["--ply-out", str(tmp_path / "x.ply"), "--out", str(src)],
                            "is the input file"),
        "device": (base + ["--out", "/dev/null"], "not a regular file"),
        "las suffix": (base + ["--las-out", str(tmp_path / "x.txt")], "must end in .las or .laz"),
        "ply suffix": (base + ["--ply-out", str(tmp_path / "x.las")], "must end in .ply"),
    }
    for name, (argv, message) in cases.items():
        code, err = _run(argv, capsys)
        assert code == 2, name
        assert message in err and err.count("\n") == 1 and "Traceback" not in err, name
    assert _names(tmp_path) == ["face.npy"]


def test_all_or_nothing_leaves_no_output_of_a_failed_run(tmp_path):
    old = tmp_path / "old.csv"
    old.write_text("the old table")
    with pytest.raises(InputError) as info:
        with all_or_nothing():
            write_atomic(tmp_path / "zones.csv", lambda fh: fh.write("zone\n1\n"))
            write_atomic(old, lambda fh: fh.write("replaced"))
            assert not (tmp_path / "zones.csv").exists()  # not before the run succeeds

            def full(fh):
                fh.write("ix\n" * 100)
                raise OSError(errno.ENOSPC, "No space left on device")

            write_atomic(tmp_path / "cells.csv", full)
    assert str(info.value) == f"cannot write {tmp_path / 'cells.csv'}: no space left on device"
    # neither the first output nor a temporary file is left; the old file is untouched
    assert _names(tmp_path) == ["old.csv"] and old.read_text() == "the old table"


def test_all_or_nothing_commits_every_file_on_success(tmp_path):
    (tmp_path / "b.csv").write_text("old b")
    with all_or_nothing():
        write_atomic(tmp_path / "a.csv", lambda fh: fh.write("new a"))
        with all_or_nothing():  # nested: joins the outer run
            write_atomic(tmp_path / "b.csv", lambda fh: fh.write("new b"))
        assert _names(tmp_path) != ["a.csv", "b.csv"]  # temporary files until the end
        assert (tmp_path / "b.csv").read_text() == "old b"
    assert _names(tmp_path) == ["a.csv", "b.csv"]
    assert [(tmp_path / n).read_text() for n in ("a.csv", "b.csv")] == ["new a", "new b"]
    write_atomic(tmp_path / "c.csv", lambda fh: fh.write("c"))  # outside a batch
    assert os.stat(tmp_path / "a.csv").st_mode == os.stat(tmp_path / "c.csv").st_mode


def test_all_or_nothing_interrupt_removes_temporaries(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        with all_or_nothing():
            write_atomic(tmp_path / "a.csv", lambda fh: fh.write("a"))
            raise KeyboardInterrupt
    assert _names(tmp_path) == []


@pytest.fixture
def full_folder(tmp_path):
    """A real 256 KiB file system (tmpfs), where the machine lets this process mount one
    (root on Linux); skipped elsewhere."""
    import shutil
    import subprocess

    folder = tmp_path / "small"
    folder.mkdir()
    if not shutil.which("mount") or os.geteuid() != 0:
        pytest.skip("mounting a small file system needs root")
    made = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(folder)],
                          capture_output=True)
    if made.returncode != 0:
        pytest.skip("this machine does not let tests mount a tmpfs")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], capture_output=True)


def test_a_laz_writer_on_a_full_disk_is_one_line_and_leaves_nothing(full_folder, capsys):
    """Issue 31: `demo generate outcrop --out FULLDISK/d.laz` ended in a traceback
    (``lazrs.LazrsError: IoError: Failed to call write``, which names no cause)."""
    out = full_folder / "d.laz"
    assert main(["demo", "generate", "outcrop", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.strip() == f"rough-viewer: error: cannot write {out}: no space left on device"
    assert list(full_folder.iterdir()) == []


def test_a_writers_io_error_without_a_cause_is_one_line(tmp_path):
    """A writer's own I/O error that names no cause, on a disk with room: one line."""

    class LazrsError(Exception):
        pass

    def fails(tmp):
        tmp.write_bytes(b"x")
        raise LazrsError("IoError: Failed to call write")

    with pytest.raises(InputError, match=r"cannot write .*d.laz: the writer failed "
                                         r"\(IoError: Failed to call write\)"):
        write_path_atomic(tmp_path / "d.laz", fails)
    assert list(tmp_path.iterdir()) == []
