"""The shape of the package: data flows one way, the science knows nothing of the UI.

Every import in ``rough_viewer`` (top-level, inside a function or under
``TYPE_CHECKING``) is read from the source and checked against the layers below. The
science packages (io, grid, lod, profiles, bias, synthetic, scale) import no UI library,
print nothing and import nothing above them. Inside the app the layers run one way
too (:data:`APP_LAYERS`), and no module of the package takes part in an import cycle.
No function of the package holds more than 80 lines of code (:func:`code_lines`; ruff's
C901 and PLR0915 bound its paths and statements, pyproject.toml).
"""

from __future__ import annotations

import ast
import functools
import io
import tokenize
import tomllib
from pathlib import Path

import pytest

import rough_viewer

ROOT = Path(rough_viewer.__file__).resolve().parent

SCIENCE = ("io", "grid", "profiles", "bias", "synthetic", "scale", "tin", "lod", "structure")

#: package -> the rough_viewer packages it may import (besides itself).
ALLOWED: dict[str, set[str]] = {
    "lazy": set(),  # PEP 562 names of the packages' __init__ modules; imports nothing
    "vocabulary": set(),
    "memory": {"vocabulary"},
    "io": {"lazy", "vocabulary", "memory"},
    "grid": {"lazy", "vocabulary", "memory", "io"},
    "profiles": {"lazy", "vocabulary", "memory", "io", "grid"},
    "bias": {"lazy", "vocabulary", "memory", "io", "grid", "profiles"},
    "synthetic": {"lazy", "vocabulary", "memory", "io", "grid"},
    "scale": {"lazy", "vocabulary", "memory", "io", "grid"},
    "tin": {"lazy", "vocabulary", "memory", "io", "grid"},
    "lod": {"lazy", "vocabulary", "memory", "io", "grid"},
    "structure": {"lazy", "vocabulary", "memory", "io", "grid", "profiles", "tin"},
    "visual": {"lazy", "vocabulary", "memory", "io", "grid", "profiles", "bias", "synthetic", "scale",
               "tin", "lod", "structure"},
    "report": {"lazy", "vocabulary", "memory", "io", "grid", "profiles", "bias", "synthetic", "scale",
               "visual", "tin", "lod", "structure"},
    "app": {"lazy", "vocabulary", "memory", "io", "grid", "profiles", "bias", "synthetic", "scale",
            "visual", "report", "tin", "lod", "structure"},
    "cli": {"lazy", "vocabulary", "memory", "io", "grid", "profiles", "bias", "synthetic", "scale",
            "visual", "report", "app", "tin", "lod", "structure", "__init__"},
    "__init__": {"_version", "lazy"},  # the flat API imports lazily (names only, for type checkers)
    "__main__": {"cli"},
    "_version": set(),
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
            if target == "_version":
                continue  # the version, a leaf module every layer may read
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


# ------------------------------------------------------------------ function length

#: Most lines of code a function of the package may hold (:func:`code_lines`).
MAX_FUNCTION_LINES = 80

#: Functions of ``rough_viewer/app/`` still longer than :data:`MAX_FUNCTION_LINES`,
#: ``"path relative to rough_viewer:function name"``; the app is being reshaped
#: (issue 32) and this list empties with it. Nothing outside ``app/`` may be here.
LONG_FUNCTIONS_ALLOWED: frozenset[str] = frozenset({
    "app/features/map.py:_add_controls",
})


def _code_line_numbers(source: str) -> set[int]:
    """Line numbers (1-based) of ``source`` holding a token that is neither a comment
    nor layout (newline, indent, dedent): blank and comment-only lines are left out."""
    layout = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT,
              tokenize.DEDENT, tokenize.ENDMARKER}
    lines: set[int] = set()
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type not in layout:
            lines.update(range(tok.start[0], tok.end[0] + 1))
    return lines


def code_lines(function: ast.FunctionDef | ast.AsyncFunctionDef, code: set[int]) -> int:
    """Lines of code of a function: the distinct line numbers spanned by the statements
    of its body (each from its first line to its last, ``lineno..end_lineno``), less
    the docstring expression (a string constant as the body's first statement), less
    the lines that hold no code (``code``, from :func:`_code_line_numbers`: blank lines
    and comment-only lines). The ``def`` line, its signature and its decorators do not
    count; a nested function's lines count in the function that holds it (and in its
    own count too)."""
    body = function.body
    if (body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
            and isinstance(body[0].value.value, str)):
        body = body[1:]
    spanned: set[int] = set()
    for statement in body:
        spanned.update(range(statement.lineno, (statement.end_lineno or statement.lineno) + 1))
    return len(spanned & code)


def _long_functions(path: Path, root: Path = ROOT) -> dict[str, int]:
    """``"path:name" -> lines of code`` of the functions of a module over the limit."""
    source = path.read_text()
    code = _code_line_numbers(source)
    rel = path.relative_to(root).as_posix()
    return {f"{rel}:{node.name}": n for node in ast.walk(ast.parse(source))
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
            and (n := code_lines(node, code)) > MAX_FUNCTION_LINES}


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_function_over_80_lines_of_code(path: Path) -> None:
    """No function holds more than :data:`MAX_FUNCTION_LINES` lines of code
    (:func:`code_lines`), but for the app's allow-list."""
    long = {k: n for k, n in _long_functions(path).items() if k not in LONG_FUNCTIONS_ALLOWED}
    assert long == {}, f"split these functions (lines of code): {long}"


def test_the_long_function_allow_list_is_the_apps_and_current() -> None:
    """Only app functions may be allowed, and each allowed one is still too long (an
    entry whose function was split or removed goes from the list)."""
    assert all(k.startswith("app/") for k in LONG_FUNCTIONS_ALLOWED)
    long: dict[str, int] = {}
    for path in MODULES:
        long |= _long_functions(path)
    assert LONG_FUNCTIONS_ALLOWED <= long.keys(), \
        f"no longer too long, take from the list: {sorted(LONG_FUNCTIONS_ALLOWED - long.keys())}"


def test_the_size_rules_exempt_only_the_app() -> None:
    """ruff's C901 (complexity) and PLR0915 (statements) cover the package; the only
    modules of ``rough_viewer`` they may skip (pyproject's per-file-ignores) are the
    app's, until it is reshaped."""
    lint = tomllib.loads((ROOT.parent / "pyproject.toml").read_text())["tool"]["ruff"]["lint"]
    assert {"C901", "PLR0915"} <= set(lint["select"])
    skipped = {pattern for pattern, rules in lint.get("per-file-ignores", {}).items()
               if {"C901", "PLR0915"} & set(rules) and pattern.startswith("rough_viewer")}
    assert all(p.startswith("rough_viewer/app/") for p in skipped), sorted(skipped)


def test_the_line_count_leaves_out_docstring_comments_and_blanks() -> None:
    """The counter itself: a docstring, a comment line and a blank line do not count;
    a statement over three lines counts three; a nested function counts in its holder."""
    source = ('def f(x):\n    """Doc\n    string."""\n    # a comment\n\n'
              '    y = (x +\n         1 +\n         2)\n    def g():\n        return y\n'
              '    return g\n')
    tree = ast.parse(source)
    code = _code_line_numbers(source)
    f, g = (n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef))
    assert code_lines(f, code) == 3 + 2 + 1
    assert code_lines(g, code) == 1


# ----------------------------------------------------------------------------- the app

#: Modules of ``rough_viewer.app`` by layer, lowest first. A module imports modules of
#: its own layer or below: the session and the worker know nothing of the host, the
#: host nothing of the UI, the UI nothing of the features, the features nothing of
#: the build (server.py), which the command line uses.
APP_LAYERS: tuple[tuple[str, frozenset[str]], ...] = (
    ("core", frozenset({"limits", "markup", "sampling", "picking", "settings", "units", "cache",
                        "colouring", "cloud", "files", "worker",
                        "session", "scene"})),
    ("host", frozenset({"host"})),
    ("ui", frozenset({"hooks", "controls", "gate", "uploads", "binding", "layout", "shell"})),
    ("features", frozenset({"features", "views"})),
    ("build", frozenset({"server", "__init__"})),
)


def _app_layer(module: str) -> int:
    """Layer index of a module named relative to ``rough_viewer.app``."""
    head = module.split(".")[0]
    for k, (_name, members) in enumerate(APP_LAYERS):
        if head in members:
            return k
    raise AssertionError(f"rough_viewer.app.{module} is in no layer: add it to APP_LAYERS")


APP_MODULES = sorted((ROOT / "app").rglob("*.py"))


def _dotted(path: Path, root: Path = ROOT) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@pytest.mark.parametrize("path", APP_MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_app_layers_flow_one_way(path: Path) -> None:
    me = _dotted(path)
    mine = _app_layer(me.removeprefix("rough_viewer.app").lstrip(".") or "__init__")
    for module in sorted(_package_graph()[me]):
        if module.startswith("rough_viewer.app."):
            target = _app_layer(module.removeprefix("rough_viewer.app."))
            assert target <= mine, (f"{me} ({APP_LAYERS[mine][0]}) imports {module} "
                                    f"({APP_LAYERS[target][0]})")


def _module_graph(modules: list[Path] | None = None, root: Path = ROOT) -> dict[str, set[str]]:
    """Every module of the package -> the modules of the package it imports (anywhere
    in its source; ``from pkg import sub`` of a submodule counts as importing ``sub``)."""
    names = {_dotted(p, root): p for p in (MODULES if modules is None else modules)}
    graph: dict[str, set[str]] = {m: set() for m in names}
    for m, p in names.items():
        package = m.split(".") if p.name == "__init__.py" else m.split(".")[:-1]
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.Import):
                graph[m] |= {a.name for a in node.names if a.name in names}
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package[:len(package) - (node.level - 1)]
                    base = ".".join(up + ([node.module] if node.module else []))
                subs = {f"{base}.{a.name}" for a in node.names} & names.keys()
                graph[m] |= subs
                if base in names and len(subs) < len(node.names):
                    graph[m].add(base)
        graph[m].discard(m)
    return graph


@functools.cache
def _package_graph() -> dict[str, set[str]]:
    return _module_graph()


def test_no_import_cycle_anywhere() -> None:
    graph = _package_graph()
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(v: str) -> None:  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    assert cycles == [], f"import cycles: {cycles}"


def test_the_cycle_check_finds_a_cycle(tmp_path: Path) -> None:
    """The checker itself: two modules importing each other inside functions."""
    pkg = tmp_path / "rough_viewer"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("def f():\n    from rough_viewer import b\n")
    (pkg / "b.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                              "    from rough_viewer.a import f\n")
    graph = _module_graph(sorted(pkg.rglob("*.py")), pkg)
    assert graph["rough_viewer.a"] == {"rough_viewer.b"}
    assert graph["rough_viewer.b"] == {"rough_viewer.a"}
