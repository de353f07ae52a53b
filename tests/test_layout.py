"""The shape of the package: data flows one way, the science knows nothing of the UI.

Every import in ``rough_viewer`` (top-level or inside a function) is read from the
source and checked against the layers below. The science packages (io, grid,
profiles, bias, synthetic, scale) import no UI library, print nothing and import
nothing above them.
"""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import pytest

import rough_viewer

ROOT = Path(rough_viewer.__file__).resolve().parent

SCIENCE = ("io", "grid", "profiles", "bias", "synthetic", "scale")

#: package -> the rough_viewer packages it may import (besides itself).
ALLOWED: dict[str, set[str]] = {
    "vocabulary": set(),
    "memory": {"vocabulary"},
    "io": {"vocabulary", "memory"},
    "grid": {"vocabulary", "memory", "io"},
    "profiles": {"vocabulary", "memory", "io", "grid"},
    "bias": {"vocabulary", "memory", "io", "grid", "profiles"},
    "synthetic": {"vocabulary", "memory", "io", "grid"},
    "scale": {"vocabulary", "memory", "io", "grid"},
    "visual": {"vocabulary", "memory", "io", "grid", "profiles", "bias", "synthetic", "scale"},
    "report": {"vocabulary", "memory", "io", "grid", "profiles", "bias", "synthetic", "scale",
               "visual"},
    "app": {"vocabulary", "memory", "io", "grid", "profiles", "bias", "synthetic", "scale",
            "visual", "report"},
    "cli": {"vocabulary", "memory", "io", "grid", "profiles", "bias", "synthetic", "scale",
            "visual", "report", "app", "__init__"},
    "__init__": set(),  # the flat API imports lazily (names only, for type checkers)
    "__main__": {"cli"},
}

#: Libraries that belong to the UI or the terminal, never to the science.
UI_LIBRARIES = {"viser", "plotly", "tqdm", "rich", "kaleido", "playwright"}


def _package_of(path: Path) -> str:
    rel = path.relative_to(ROOT)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def _imports(path: Path) -> list[tuple[str, int]]:
    tree = ast.parse(path.read_text(), filename=str(path))
    found: list[tuple[str, int]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.module, node.lineno))
            if node.module == "rough_viewer":
                found += [(f"rough_viewer.{a.name}", node.lineno) for a in node.names]
    return found


MODULES = sorted(ROOT.rglob("*.py"))


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_flow_one_way(path: Path) -> None:
    package = _package_of(path)
    assert package in ALLOWED, f"new top-level package {package!r}: add it to ALLOWED"
    allowed = ALLOWED[package] | {package}
    for module, line in _imports(path):
        parts = module.split(".")
        if parts[0] == "rough_viewer" and len(parts) > 1:
            target = parts[1]
            if target.startswith("__"):
                continue  # __version__ of the root package, which imports nothing
            if package == "__init__" and target != "__init__":
                continue  # TYPE_CHECKING names of the flat API
            assert target in allowed, f"{path.name}:{line} ({package}) imports {module}"
        if package in SCIENCE:
            assert parts[0] not in UI_LIBRARIES, f"{path.name}:{line} imports {module}"


@pytest.mark.parametrize("path", [p for p in MODULES if _package_of(p) in SCIENCE
                                  and p.name != "__main__.py"],  # program entries may print
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_science_prints_nothing(path: Path) -> None:
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
            assert node.func.id not in ("print", "input"), f"{path.name}:{node.lineno}"
        if isinstance(node, ast.Attribute) and node.attr in ("stdout", "stderr"):
            assert not (isinstance(node.value, ast.Name) and node.value.id == "sys"), \
                f"{path.name}:{node.lineno} writes to the terminal"


def test_every_package_is_installed() -> None:
    """pyproject lists packages by hand (the demo data maps in); none may be missing."""
    config = tomllib.loads((ROOT.parent / "pyproject.toml").read_text())
    listed = set(config["tool"]["setuptools"]["packages"])
    found = {"rough_viewer." + ".".join(p.parent.relative_to(ROOT).parts)
             for p in ROOT.rglob("__init__.py") if p.parent != ROOT} | {"rough_viewer"}
    assert found <= listed, f"add to pyproject [tool.setuptools] packages: {found - listed}"
    assert "rough_viewer.demo_data" in listed


def test_flat_api_names_resolve() -> None:
    for name in rough_viewer.__all__:
        assert getattr(rough_viewer, name) is not None, name
