"""``serve --memory`` (issue 33 item 4): inputs larger than the server may hold are
refused from their headers, in one line, before any point is read; files that fit
still serve, and the File tab refuses the same files with a notice."""

from __future__ import annotations

import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rough_viewer.app.limits import (
    APP_BYTES_PER_POINT,
    APP_CACHE_BYTES_PER_POINT,
    APP_FIXED_BYTES,
    CACHE_BYTES,
)
from rough_viewer.cli import main
from rough_viewer.io.estimates import COSTS
from rough_viewer.memory import format_bytes

GB = 1_000_000_000


def _laz(path: Path, n: int = 5000, *, seed: int = 0, compress: bool = True) -> Path:
    """A real LAS/LAZ of ``n`` points on a 2 m x 2 m rough face (laspy)."""
    import laspy

    hdr = laspy.LasHeader(point_format=1, version="1.2")
    hdr.scales, hdr.offsets = [0.0001] * 3, [0.0, 0.0, 0.0]
    las = laspy.LasData(hdr)
    rng = np.random.default_rng(seed)
    las.x, las.z = rng.uniform(0.0, 2.0, (2, n))
    las.y = rng.normal(0.0, 0.003, n)
    las.write(str(path), do_compress=compress)
    return path


def _declaring(path: Path, declared: int) -> Path:
    """``path`` with the header's (legacy, LAS 1.2) point count set to ``declared``."""
    data = bytearray(path.read_bytes())
    struct.pack_into("<I", data, 107, declared)
    path.write_bytes(bytes(data))
    return path


#: Runs its arguments as a command and prints its exit status and peak resident memory
#: (bytes): a small process of its own, since a forked child's peak counts the pages
#: of the process it was forked from (pytest's, hundreds of MB).
_MEASURED = """
import resource, subprocess, sys
rc = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL).returncode
print(rc, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024)
"""


def _need(points: int, read_per_point: float) -> float:
    """The server's peak ``serve --memory`` is checked against, from the constants."""
    return (read_per_point * points + APP_FIXED_BYTES + APP_BYTES_PER_POINT * points
            + min(CACHE_BYTES, APP_CACHE_BYTES_PER_POINT * points))


def test_a_laz_declaring_a_billion_points_is_refused_before_any_point_is_read(tmp_path):
    """A real 5,000-point LAZ whose header declares 1,000,000,000 (let through the
    decompression-bomb guard by --max-points): one line on stderr, status 2, no
    traceback, no server opened, and the process never grew (its peak RSS: the
    interpreter and the package's imports, far below the 90 GB its read would take)."""
    big = _declaring(_laz(tmp_path / "big.laz"), 1_000_000_000)
    done = subprocess.run(
        [sys.executable, "-c", _MEASURED, sys.executable, "-m", "rough_viewer", "serve",
         str(big), "--memory", "4GB", "--max-points", "1000000000", "--port", "0",
         "--no-block"], capture_output=True, text=True, timeout=120)
    err = done.stderr
    rc, peak = (int(v) for v in done.stdout.split())
    assert rc == 2, err
    assert peak < 500 << 20  # nothing was allocated (the imports: ~150 MB)
    lines = err.splitlines()
    assert len(lines) == 1 and "Traceback" not in err and "listening" not in err, err
    need = format_bytes(_need(1_000_000_000, COSTS["laz"].per_point))
    assert lines[0] == (
        f"rough-viewer: error: {big}: 1,000,000,000 points need about {need} in the server, "
        f"more than --memory 4GB allows; index the survey once with 'rough-viewer index "
        f"{big} --out campaign.copc.laz' and compute its map out of core with 'rough-viewer "
        "compute campaign.copc.laz --memory 4GB --grid G --out cells.csv'")


def test_the_default_budget_is_what_the_machine_has(tmp_path, capsys):
    """Without --memory the budget is 80 % of the memory available: the same file is
    refused, naming that budget; --memory larger than the need lets it through to its
    read (which then finds the points its header lied about missing)."""
    from rough_viewer.app.files import default_memory

    budget = default_memory()
    need = _need(1_000_000_000, COSTS["laz"].per_point)
    if budget is None or budget >= need:
        pytest.skip("needs a machine with less than ~200 GB available")
    big = _declaring(_laz(tmp_path / "big.laz"), 1_000_000_000)
    assert main(["serve", str(big), "--max-points", "1000000000", "--port", "0",
                 "--no-block"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "this machine can give (80 % of the memory available" in err
    assert "rough-viewer index" in err
    small = _declaring(_laz(tmp_path / "small.laz"), 20_000)
    assert main(["serve", str(small), "--max-points", "20000", "--memory", "3GB",
                 "--port", "0", "--no-block"]) == 2
    err = capsys.readouterr().err
    assert "points need about" not in err and "listening at" in err  # let through:
    assert f"cannot read {small}" in err  # its read finds the missing points


def test_a_small_file_fits_and_serves_and_a_small_budget_refuses_it(tmp_path, capsys):
    """The 5,000-point LAZ needs APP_FIXED_BYTES and a little more: it serves with
    the default budget and with --memory 1GB, and 100MB refuses it; a bad --memory is
    refused too (as compute does)."""
    path = _laz(tmp_path / "face.laz")
    assert main(["serve", str(path), "--port", "0", "--grid", "0.5", "--no-block"]) == 0
    assert "5,000 points, open http://127.0.0.1:" in capsys.readouterr().out
    assert main(["serve", str(path), "--memory", "1GB", "--port", "0", "--grid", "0.5",
                 "--no-block"]) == 0
    assert "5,000 points, open http://127.0.0.1:" in capsys.readouterr().out
    assert main(["serve", str(path), "--memory", "100MB", "--port", "0", "--no-block"]) == 2
    err = capsys.readouterr().err
    need = format_bytes(_need(5000, COSTS["laz"].per_point))
    assert err.count("\n") == 1 and f"5,000 points need about {need} in the server, " \
        "more than --memory 100MB allows" in err
    assert main(["serve", "--memory", "lots", "--no-block"]) == 2
    assert "--memory expects a size such as 2GB" in capsys.readouterr().err


def test_several_inputs_and_a_glob_count_together(tmp_path, capsys):
    """Each of two LAS files (uncompressed, 10,000,000 points each by their headers)
    fits in 3 GB alone; both, through a quoted glob, need their sum and are refused,
    the glob named in the index command as typed. An uncompressed LAS counts only the
    points its data can hold (a header that declares more is a truncated file, which
    its read refuses as such)."""
    from rough_viewer.app.files import serve_need

    n = 10_000_000
    record = 28  # point format 1
    parts = []
    for i in range(2):
        p = _laz(tmp_path / f"part{i}.las", 1000, seed=i, compress=False)
        with open(p, "r+b") as fh:  # the data of n points (zeros), as the header says
            fh.truncate(struct.unpack_from("<I", p.read_bytes()[:100], 96)[0] + n * record)
        parts.append(_declaring(p, n))
    one, both = serve_need(parts[:1]), serve_need(parts)
    assert one.points == n and both.points == 2 * n
    assert one.total == pytest.approx(_need(n, COSTS["las"].per_point))
    assert both.total == pytest.approx(COSTS["las"].per_point * n + APP_FIXED_BYTES
                                       + APP_BYTES_PER_POINT * 2 * n + min(CACHE_BYTES, APP_CACHE_BYTES_PER_POINT * 2 * n))
    assert one.total <= 3 * GB < both.total
    pattern = str(tmp_path / "part*.las")
    assert main(["serve", pattern, "--memory", "3GB", "--port", "0", "--no-block"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert f"2 files: {parts[0]}, {parts[1]}: 20,000,000 points need about " \
           f"{format_bytes(both.total)}" in err
    assert f"'rough-viewer index '{pattern}' --out campaign.copc.laz'" in err
    truncated = _declaring(_laz(tmp_path / "cut.las", 1000, compress=False), 10 * n)
    assert serve_need([truncated]).points == 1000


def test_a_copc_input_is_told_to_compute_not_to_index(tmp_path, capsys):
    """A COPC file (written by rough-viewer index) too big for --memory: serving a
    COPC campaign larger than memory is not built yet; compute --memory is."""
    src = _laz(tmp_path / "face.laz")
    copc = tmp_path / "campaign.copc.laz"
    assert main(["index", str(src), "--out", str(copc)]) == 0
    capsys.readouterr()
    assert main(["serve", str(copc), "--memory", "100MB", "--port", "0", "--no-block"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "rough-viewer index" not in err
    assert "serving a COPC campaign larger than memory is not built yet" in err
    assert f"'rough-viewer compute {copc} --memory 100MB --grid G --out cells.csv'" in err
    from rough_viewer.io.copc.reader import is_copc

    assert is_copc(copc) and not is_copc(src)


def test_the_file_tab_refuses_a_file_too_big_for_the_budget(tmp_path):
    """A file loaded from the File tab that needs more than the server's --memory is
    a notice naming it, read from its header only; the shown cloud stays. Without a
    budget the same file loads."""
    import viser

    from rough_viewer.app.server import build_app
    from rough_viewer.io import load_points

    start = load_points(_laz(tmp_path / "start.laz", 3000))
    _laz(tmp_path / "next.laz", 4000, seed=1)
    budget = _need(3500, COSTS["laz"].per_point)  # between the two files' needs
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, start, prefetch=False, variogram=False, data_dir=tmp_path,
                    memory=budget)
    try:
        assert app.wait_idle(60)
        app.load(path="next.laz")
        assert app.wait_idle(60)
        need = format_bytes(_need(4000, COSTS["laz"].per_point))
        assert app.host.errors[-1].endswith(
            f"next.laz: 4,000 points need about {need} in the server, more than the "
            f"server's {format_bytes(budget)} allows (serve --memory): index the survey "
            "with 'rough-viewer index' and compute its map out of core with "
            "'rough-viewer compute --memory'"), app.host.errors[-1]
        assert str(tmp_path) not in app.host.errors[-1]
        assert app.session.shown.loaded.cloud is start
        app.load(path="start.laz")  # 3,000 points fit
        assert app.wait_idle(60)
        assert app.session.shown.loaded.n_total == 3000
    finally:
        app.stop()
        server.stop()
