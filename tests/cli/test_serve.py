import re

import numpy as np
import pytest

from rough_viewer.cli import main


def _cloud(tmp_path):
    rng = np.random.default_rng(0)
    xyz = np.column_stack([rng.uniform(0, 2, 5000), rng.uniform(0, 2, 5000),
                           rng.normal(0, 0.003, 5000)])
    path = tmp_path / "pts.npy"
    np.save(path, xyz)
    return path


def test_serve_starts_prints_url_with_a_token_and_stops(tmp_path, capsys):
    path = _cloud(tmp_path)
    assert main(["serve", str(path), "--port", "0", "--grid", "0.5", "--no-block"]) == 0
    out = capsys.readouterr().out
    m = re.search(r"5,000 points, open http://127\.0\.0\.1:\d+/t/([A-Za-z0-9_-]{32})/$", out,
                  re.MULTILINE)
    assert m, out
    assert "Websocket" not in out  # viser's banner (a URL without the token) is not shown
    assert main(["serve", str(path), "--port", "0", "--no-block"]) == 0
    assert re.search(r"/t/([A-Za-z0-9_-]{32})/$", capsys.readouterr().out, re.MULTILINE).group(1) \
        != m.group(1)  # a new token every start


def test_serve_without_token(tmp_path, capsys):
    path = _cloud(tmp_path)
    assert main(["serve", str(path), "--port", "0", "--no-token", "--no-block",
                 "--allow-origin", "http://lab.example:8080", "--data-dir", str(tmp_path),
                 "--max-upload-mb", "10"]) == 0
    assert re.search(r"open http://127\.0\.0\.1:\d+/$", capsys.readouterr().out, re.MULTILINE)


def test_serve_bad_input_exits_2(tmp_path, capsys):
    assert main(["serve", str(tmp_path / "nope.las"), "--port", "0", "--no-block"]) == 2
    assert main(["serve", "x.npy", "--grid", "0", "--no-block"]) == 2
    assert main(["serve", "x.npy", "--demo", "outcrop", "--no-block"]) == 2
    assert main(["serve", "--allow-origin", "evil", "--no-block"]) == 2
    assert main(["serve", "--data-dir", str(tmp_path / "none"), "--no-block"]) == 2
    assert main(["serve", "--max-upload-mb", "0", "--no-block"]) == 2
    err = capsys.readouterr().err
    assert err.count("rough-viewer: error:") == 6 and "Traceback" not in err
    assert "--allow-origin wants an origin" in err and "--data-dir is not a folder" in err


def test_serve_merges_several_inputs_and_globs(tmp_path, capsys):
    rng = np.random.default_rng(1)
    for i in range(3):
        xyz = np.column_stack([rng.uniform(0, 2, 2000) + i, rng.uniform(0, 2, 2000),
                               rng.normal(0, 0.003, 2000)])
        np.save(tmp_path / f"part{i}.npy", xyz)
    assert main(["serve", str(tmp_path / "part*.npy"), "--port", "0", "--grid", "0.5",
                 "--no-block"]) == 0
    assert "6,000 points, open http://127.0.0.1:" in capsys.readouterr().out


def _labels_and_status(proc_args):
    """Start ``serve`` with ``proc_args`` as a real process; the grid dropdown's
    label and options and the status line it sends."""
    from tests.app.protocol import ProtocolClient
    from tests.app.serve_process import ServeProcess

    proc = ServeProcess(*proc_args, "--no-token")
    client = ProtocolClient(proc.port, "/")
    try:
        grid = client.wait_for(lambda m: m.get("type") == "GuiDropdownMessage"
                               and str(m["props"].get("label", "")).startswith("Grid size"),
                               what="the grid dropdown")
        status = client.wait_for(lambda m: "each tab draws up to" in str(m), what="the status")
        return grid["props"]["label"], tuple(grid["props"]["options"]), grid["value"], str(status)
    finally:
        client.close()
        proc.stop()


def test_serve_units_from_the_option_and_from_the_las_crs(tmp_path):
    import laspy

    from tests.helpers import face_cloud

    xyz = face_cloud(8000).xyz()
    local = xyz - xyz.min(axis=0)
    np.save(tmp_path / "joint.npy", local * 1000.0)  # the face in millimetres
    label, options, value, status = _labels_and_status(
        [str(tmp_path / "joint.npy"), "--units", "mm"])
    assert label == "Grid size (mm)"
    assert options == ("1200", "600", "300", "150", "free") and value == "150"
    assert "grid 150 mm" in status
    # --grid is in --units too
    label, _, value, status = _labels_and_status(
        [str(tmp_path / "joint.npy"), "--units", "mm", "--grid", "600"])
    assert value == "600" and "grid 600 mm" in status
    # a LAS whose CRS is in US survey feet: feet without --units
    wkt = ('PROJCS["NAD83 / California zone 3 (ftUS)",GEOGCS["NAD83",DATUM["D",SPHEROID["GRS 1980",'
           '6378137,298.257222101]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]],'
           'PROJECTION["Lambert_Conformal_Conic_2SP"],UNIT["US survey foot",0.304800609601219],'
           'AUTHORITY["EPSG","2227"]]')
    hdr = laspy.LasHeader(point_format=3, version="1.4")
    hdr.scales = np.array([1e-4] * 3)
    hdr.vlrs.append(laspy.VLR("LASF_Projection", 2112, "", wkt.encode() + b"\0"))
    las = laspy.LasData(hdr)
    feet = local / 0.3048006096
    las.x, las.y, las.z = feet.T
    las.write(str(tmp_path / "face_ft.las"))
    label, options, value, status = _labels_and_status([str(tmp_path / "face_ft.las")])
    assert label == "Grid size (US ft)"
    assert options[-2] == value and f"grid {value} US ft" in status
    assert float(value) in (0.25, 0.3, 0.4, 0.5)  # a readable size in feet


def test_serve_rejects_units_with_a_demo(capsys):
    assert main(["serve", "--demo", "outcrop-small", "--units", "mm", "--no-block"]) == 2
    assert "--units applies to INPUT files" in capsys.readouterr().err


@pytest.mark.parametrize("signame", ["SIGTERM", "SIGHUP"])
def test_terminate_cleans_up_like_ctrl_c(tmp_path, monkeypatch, signame):
    """A service manager's SIGTERM (or a closed terminal's SIGHUP) left the upload
    folder behind in the temp folder; now it ends the server as Ctrl-C does."""
    import os
    import signal

    from tests.app.serve_process import ServeProcess

    xyz = np.random.default_rng(3).uniform(0, 2, (3000, 3)) * [1, 1, 0.01]
    np.save(tmp_path / "face.npy", xyz)
    temp = tmp_path / "tmp"
    temp.mkdir()
    monkeypatch.setenv("TMPDIR", str(temp))
    proc = ServeProcess(str(tmp_path / "face.npy"), "--no-token")
    try:
        assert [p.name.startswith("rough-viewer-uploads-") for p in temp.iterdir()] == [True]
        os.kill(proc.proc.pid, getattr(signal, signame))
        assert proc.proc.wait(20) == 0
        assert list(temp.iterdir()) == []
    finally:
        proc.stop()


def test_serve_says_a_files_warnings_once(tmp_path, capsys):
    """A file whose CRS is geographic: the warning on stderr once (it was printed by
    the reading and again by serve)."""
    import laspy

    hdr = laspy.LasHeader(point_format=1, version="1.2")
    hdr.scales = np.array([1e-7, 1e-7, 1e-3])
    hdr.vlrs.append(laspy.VLR("LASF_Projection", 2112, "", b'GEOGCS["WGS 84",UNIT["degree",'
                              b'0.0174532925199433],AUTHORITY["EPSG","4326"]]\0'))
    las = laspy.LasData(hdr)
    rng = np.random.default_rng(0)
    las.x, las.y = -122 + rng.uniform(0, 1e-3, 2000), 37 + rng.uniform(0, 1e-3, 2000)
    las.z = rng.uniform(0, 5, 2000)
    path = tmp_path / "geo.las"
    las.write(str(path))
    assert main(["serve", str(path), "--port", "0", "--grid", "0.001", "--no-block"]) == 0
    assert capsys.readouterr().err.count("is geographic (degrees)") == 1


def test_serve_says_its_address_first_and_answers_while_it_reads(tmp_path):
    """Issue 31: a fresh serve printed its URL 30-60 s after start on a loaded machine
    (after the cloud and its first map). The address comes first (stderr), the page
    answers at once, and the usual "N points, open URL" line follows when ready."""
    import subprocess
    import sys
    import time
    import urllib.request

    path = _cloud(tmp_path)
    proc = subprocess.Popen(
        [sys.executable, "-c", "from rough_viewer.cli import main; raise SystemExit(main())",
         "serve", str(path), "--port", "0", "--grid", "0.5"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, bufsize=1)
    try:
        assert proc.stderr is not None and proc.stdout is not None
        first = proc.stderr.readline()
        m = re.search(r"^rough-viewer: listening at (http://127\.0\.0\.1:\d+/t/[A-Za-z0-9_-]{32}/)"
                      r" ; reading pts\.npy, the page fills in once it is ready$", first.strip())
        assert m, first
        url = m.group(1)
        end = time.time() + 30
        while True:  # the page is served while the cloud is read and its first map made
            try:
                with urllib.request.urlopen(url, timeout=5) as page:
                    assert page.status == 200
                break
            except OSError:
                assert time.time() < end
                time.sleep(0.1)
        ready = proc.stdout.readline()
        assert ready.strip() == f"rough-viewer: 5,000 points, open {url}"
    finally:
        proc.terminate()
        proc.wait(30)


def test_point_budget_and_max_points_each_mean_one_thing(tmp_path, capsys):
    """Issue 32 item 5: --point-budget is the display budget only, --max-points the
    decompression-bomb guard only (as in compute): neither sets the other."""
    from rough_viewer.cli import build_parser
    from tests.io.crafted import laz_declaring

    args = build_parser("serve").parse_args(["serve", "--max-points", "5000000"])
    assert (args.file_max_points, args.point_budget) == (5_000_000, None)
    args = build_parser("serve").parse_args(["serve", "--point-budget", "100000"])
    assert (args.file_max_points, args.point_budget) == (None, 100_000)
    bomb = laz_declaring(tmp_path / "bomb.laz", 3_000_000)  # beyond the default 2,000,000
    # a point budget above its points does not let it in (it did when it was an alias)
    assert main(["serve", str(bomb), "--point-budget", "5000000", "--port", "0",
                 "--no-block"]) == 2
    assert "decompression bomb" in capsys.readouterr().err
    # --max-points does (the read then fails on the points the file lacks)
    main(["serve", str(bomb), "--max-points", "5000000", "--port", "0", "--no-block"])
    assert "decompression bomb" not in capsys.readouterr().err


@pytest.mark.parametrize("budget", ["5000", "0", "-3", "60000000"])
def test_a_point_budget_the_map_control_cannot_show_is_one_line(tmp_path, capsys, budget):
    """A budget outside the Map tab's control (10,000-50,000,000) was a traceback from the
    GUI's slider; it is refused before the server starts, naming the option and its range."""
    path = _cloud(tmp_path)
    assert main(["serve", str(path), "--point-budget", budget, "--port", "0",
                 "--no-block"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.count("\n") == 1 and "--point-budget must be 10,000-50,000,000" in err, err


def test_serve_classroom_prints_a_students_and_a_teachers_address(tmp_path, capsys):
    """``serve --classroom``: ``open URL`` then ``teacher URL``, each on its own line with
    its own token; a real WebSocket with the teacher's token opens the teacher's tab."""
    path = _cloud(tmp_path)
    assert main(["serve", str(path), "--port", "0", "--classroom", "--no-block"]) == 0
    out = capsys.readouterr().out
    student = re.search(r"^open http://127\.0\.0\.1:(\d+)/t/([A-Za-z0-9_-]{32})/$", out,
                        re.MULTILINE)
    teacher = re.search(r"^teacher http://127\.0\.0\.1:(\d+)/t/([A-Za-z0-9_-]{32})/$", out,
                        re.MULTILINE)
    assert student and teacher, out
    assert student.group(1) == teacher.group(1)
    assert student.group(2) != teacher.group(2)
    assert out.index("open http") < out.index("teacher http")


def test_serve_classroom_needs_the_tokens(tmp_path, capsys):
    path = _cloud(tmp_path)
    assert main(["serve", str(path), "--port", "0", "--classroom", "--no-token",
                 "--no-block"]) == 2
    err = capsys.readouterr().err
    assert "--classroom needs the tokens" in err and "Traceback" not in err
