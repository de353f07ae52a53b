"""A wheel of the package carries everything it needs, the demo scans included, so
`pip install .` (not only `pip install -e .`) opens the demo."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_wheel_holds_every_package_and_opens_its_demo(tmp_path: Path) -> None:
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps",
                    "--no-build-isolation", "-w", str(tmp_path / "dist"), str(ROOT)],
                   check=True, capture_output=True, timeout=300)
    wheel = next((tmp_path / "dist").glob("rough_viewer-*.whl"))
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
        zf.extractall(tmp_path / "site")
    for path in ROOT.joinpath("rough_viewer").rglob("*.py"):
        assert path.relative_to(ROOT).as_posix() in names, path
    assert "rough_viewer/demo_data/outcrop.laz" in names
    assert "rough_viewer/py.typed" in names
    # the unpacked wheel, not this checkout, answers the import (run from elsewhere)
    code = ("import rough_viewer, rough_viewer.synthetic.demos as d; "
            "print(rough_viewer.__file__); print(d.load_demo('outcrop-small').n)")
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120,
                          env={"PYTHONPATH": str(tmp_path / "site"), "PATH": "/usr/bin:/bin",
                               "HOME": str(tmp_path)})
    assert done.returncode == 0, done.stderr[-2000:]
    where, n = done.stdout.split()
    assert where.startswith(str(tmp_path / "site"))
    assert int(n) == 153_385
