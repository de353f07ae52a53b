import re

import numpy as np

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
