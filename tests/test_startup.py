"""Start-up by need: ``import rough_viewer``, reading a cloud and ``rough-viewer compute``
import none of the libraries they do not use (each run in a fresh interpreter, which
then lists what it imported). A behaviour, not a timing: SciPy, plotly, viser,
pyarrow and Dask each cost 0.1-0.5 s of every start they are loaded on."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

#: Libraries the compute path never needs.
NOT_ON_THE_COMPUTE_PATH = ("scipy", "plotly", "viser", "pyarrow", "dask", "distributed",
                           "pywt", "kaleido", "laspy", "pye57", "plyfile", "tqdm", "cmap",
                           "msgspec")


def imported_after(code: str, tmp_path: Path, **env: str) -> set[str]:
    """Top-level packages a fresh interpreter has imported after running ``code``."""
    code += "\nimport sys, json; print(json.dumps(sorted({m.split('.')[0] for m in sys.modules})))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, cwd=tmp_path, env=dict(os.environ, **env))
    assert done.returncode == 0, done.stderr[-2000:]
    return set(json.loads(done.stdout.splitlines()[-1]))


def forbidden(modules: set[str]) -> list[str]:
    return sorted(m for m in NOT_ON_THE_COMPUTE_PATH if m in modules)


@pytest.fixture
def cloud_npy(tmp_path: Path) -> Path:
    rng = np.random.default_rng(0)
    xyz = np.column_stack([rng.uniform(0, 4, 20_000), rng.uniform(0, 4, 20_000),
                           0.01 * rng.standard_normal(20_000)])
    np.save(tmp_path / "cloud.npy", xyz)
    return tmp_path / "cloud.npy"


def test_import_rough_viewer_imports_no_library_but_numpy(tmp_path: Path) -> None:
    mods = imported_after("import rough_viewer", tmp_path)
    assert forbidden(mods) == []
    assert "numpy" not in mods and "numba" not in mods  # names load on first use


def test_reading_a_npy_imports_no_reader_of_other_formats(tmp_path: Path, cloud_npy: Path) -> None:
    mods = imported_after(f"import rough_viewer; rough_viewer.load_points({str(cloud_npy)!r})",
                          tmp_path)
    assert forbidden(mods) == [] and "numba" not in mods


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_compute_imports_only_what_it_uses(tmp_path: Path, cloud_npy: Path, engine: str) -> None:
    out = tmp_path / f"cells-{engine}.csv"
    code = ("from rough_viewer.cli import main; "
            f"assert main(['compute', {str(cloud_npy)!r}, '--grid', '0.5', '--out', "
            f"{str(out)!r}, '--summary-json', {str(out.with_suffix('.json'))!r}, "
            "'--quiet']) == 0")
    mods = imported_after(code, tmp_path, ROUGH_VIEWER_ENGINE=engine)
    assert out.stat().st_size > 0
    assert forbidden(mods) == []
    assert ("numba" in mods) == (engine == "numba")
    # only the compute command's modules: no other command was imported
    assert "rough_viewer" in mods
    code = ("from rough_viewer.cli import main; import json, sys; "
            f"main(['compute', {str(cloud_npy)!r}, '--grid', '0.5', '--out', "
            f"{str(tmp_path / 'again.csv')!r}, '--quiet']); "
            "print(json.dumps([m for m in sys.modules if m.startswith('rough_viewer.cli.')]))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, cwd=tmp_path, check=True)
    modules = {m.split(".")[2] for m in json.loads(done.stdout.strip().splitlines()[-1])}
    assert {m for m in modules if not m.startswith("_")} == {"compute"}  # helpers are _named
