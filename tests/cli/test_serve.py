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


def test_serve_merges_several_inputs_and_globs(tmp_path, capsys):
    rng = np.random.default_rng(1)
    for i in range(3):
        xyz = np.column_stack([rng.uniform(0, 2, 2000) + i, rng.uniform(0, 2, 2000),
                               rng.normal(0, 0.003, 2000)])
        np.save(tmp_path / f"part{i}.npy", xyz)
    assert main(["serve", str(tmp_path / "part*.npy"), "--port", "0", "--grid", "0.5",
                 "--no-block"]) == 0
    assert "6,000 points, open http://127.0.0.1:" in capsys.readouterr().out
