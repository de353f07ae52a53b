import numpy as np

from rough_viewer.cli import main


def test_serve_starts_prints_url_and_stops(tmp_path, capsys):
    rng = np.random.default_rng(0)
    xyz = np.column_stack([rng.uniform(0, 2, 5000), rng.uniform(0, 2, 5000),
                           rng.normal(0, 0.003, 5000)])
    path = tmp_path / "pts.npy"
    np.save(path, xyz)
    assert main(["serve", str(path), "--port", "0", "--grid", "0.5", "--no-block"]) == 0
    out = capsys.readouterr().out
    assert "5,000 points, open http://127.0.0.1:" in out


def test_serve_bad_input_exits_2(tmp_path, capsys):
    assert main(["serve", str(tmp_path / "nope.las"), "--port", "0", "--no-block"]) == 2
    assert main(["serve", "x.npy", "--grid", "0", "--no-block"]) == 2
    assert main(["serve", "x.npy", "--demo", "outcrop", "--no-block"]) == 2
    err = capsys.readouterr().err
    assert err.count("rough-viewer: error:") == 3 and "Traceback" not in err
