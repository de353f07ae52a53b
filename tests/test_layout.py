"""The shape of the package: data flows one way, the science knows nothing of the UI.

Every import in ``rough_viewer`` (top-level, inside a function or under
``TYPE_CHECKING``) is read from the source and checked against the layers below. The
science packages (:data:`SCIENCE`) import no UI library, print nothing and import
nothing above them. Inside the app the layers run one way
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
from collections.abc import Iterator
from pathlib import Path

import pytest

import rough_viewer

ROOT = Path(rough_viewer.__file__).resolve().parent

SCIENCE = ("io", "grid", "profiles", "bias", "synthetic", "scale", "tin", "lod", "structure",
           "scanner", "directions")

#: package -> the rough_viewer packages it may import (besides itself).
ALLOWED: dict[str, set[str]] = {
    "lazy": set(),  # PEP 562 names of the packages' __init__ modules; imports nothing
    "vocabulary": set(),
    "memory": {"vocabulary"},
    "io": {"lazy", "vocabulary", "memory"},
    "grid": {"lazy", "vocabulary", "memory", "io"},
    "profiles": {"lazy", "vocabulary", "memory", "io", "grid"},
    "bias": {"lazy", "vocabulary", "memory", "io", "grid", "profiles"},
    "synthetic": {"lazy", "vocabulary", "memory", "io", "grid", "scanner"},
    "scale": {"lazy", "vocabulary", "memory", "io", "grid"},
    "tin": {"lazy", "vocabulary", "memory", "io", "grid"},
    "lod": {"lazy", "vocabulary", "memory", "io", "grid"},
    "structure": {"lazy", "vocabulary", "memory", "io", "grid", "profiles", "tin"},
    "scanner": {"lazy", "vocabulary", "memory", "io", "grid", "bias"},
    "directions": {"lazy", "vocabulary", "memory", "io", "grid", "profiles", "tin"},
    "visual": {"lazy", "vocabulary", "memory", "io", "grid", "profiles", "bias", "synthetic", "scale",
               "tin", "lod", "structure", "scanner", "directions"},
    "report": {"lazy", "vocabulary", "memory", "io", "grid", "profiles", "bias", "synthetic", "scale",
               "visual", "tin", "lod", "structure", "scanner", "directions"},
    "lessons": {"lazy", "vocabulary", "memory", "io", "grid", "synthetic", "visual", "report"},
    "app": {"lazy", "vocabulary", "memory", "io", "grid", "profiles", "bias", "synthetic", "scale",
            "visual", "report", "lessons", "tin", "lod", "structure", "scanner", "directions"},
    "cli": {"lazy", "vocabulary", "memory", "io", "grid", "profiles", "bias", "synthetic", "scale",
            "visual", "report", "lessons", "app", "tin", "lod", "structure", "scanner", "directions", "__init__"},
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
    (:func:`code_lines`)."""
    long = _long_functions(path)
    assert long == {}, f"split these functions (lines of code): {long}"


def test_the_size_rules_exempt_no_module_of_the_package() -> None:
    """ruff's C901 (complexity) and PLR0915 (statements) cover the whole package: no
    module of ``rough_viewer`` skips them (pyproject's per-file-ignores)."""
    lint = tomllib.loads((ROOT.parent / "pyproject.toml").read_text())["tool"]["ruff"]["lint"]
    assert {"C901", "PLR0915"} <= set(lint["select"])
    skipped = {pattern for pattern, rules in lint.get("per-file-ignores", {}).items()
               if {"C901", "PLR0915"} & set(rules) and pattern.startswith("rough_viewer")}
    assert not skipped, sorted(skipped)


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
    # hooks: where the app reaches into viser (it imports nothing of the app); stage:
    # the server's GUI and scene or one tab's, which the scene and the shell are built on
    ("core", frozenset({"limits", "markup", "sampling", "picking", "settings", "units", "cache",
                        "colouring", "store", "cloud", "campaign", "campaign_nodes", "files",
                        "worker", "session", "hooks", "stage", "scene"})),
    ("host", frozenset({"host", "detail"})),  # detail: the scene's level-of-detail jobs
    ("ui", frozenset({"controls", "gate", "uploads", "binding", "layout", "shell"})),
    ("features", frozenset({"features", "views"})),
    # classroom: one app per tab (``serve --classroom``), built with server's mount_app
    ("build", frozenset({"server", "classroom", "__init__"})),
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


# ----------------------------------------------------------------------------- features

FEATURES = ROOT / "app" / "features"
FEATURE_MODULES = sorted(FEATURES.rglob("*.py"))


def _feature_of(module: str) -> str | None:
    """``rough_viewer.app.features.<a>[...]`` -> ``a`` (None: not a feature's module)."""
    parts = module.split(".")
    return parts[3] if parts[:3] == ["rough_viewer", "app", "features"] and len(parts) > 3 \
        else None


@pytest.mark.parametrize("path", FEATURE_MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_feature_imports_another(path: Path) -> None:
    """A feature (``features/<a>.py``, or the package ``features/<a>/``) imports only its
    own modules: what it needs of the map or of another feature goes through its
    :class:`~rough_viewer.app.host.Host` (anywhere in the source, ``TYPE_CHECKING``
    included)."""
    me = _dotted(path)
    mine = _feature_of(me)
    for module in sorted(_package_graph()[me]):
        theirs = _feature_of(module)
        assert theirs is None or theirs == mine, f"{me} imports {module}"


def test_the_feature_check_finds_a_feature_import(tmp_path: Path) -> None:
    pkg = tmp_path / "rough_viewer"
    (pkg / "app" / "features" / "a").mkdir(parents=True)
    for init in (pkg, pkg / "app", pkg / "app" / "features", pkg / "app" / "features" / "a"):
        (init / "__init__.py").write_text("")
    (pkg / "app" / "features" / "b.py").write_text("")
    (pkg / "app" / "features" / "a" / "x.py").write_text(
        "from rough_viewer.app.features import b\nfrom rough_viewer.app.features.a import y\n")
    (pkg / "app" / "features" / "a" / "y.py").write_text("")
    graph = _module_graph(sorted(pkg.rglob("*.py")), pkg)
    found = {_feature_of(m) for m in graph["rough_viewer.app.features.a.x"]}
    assert found == {"a", "b"}


# ----------------------------------------------------------------------------- callbacks

#: Methods that register a callback viser (or the upload stream) calls on its own
#: threads, and the position of the callback among their arguments.
REGISTRATIONS = {"on_change": 1, "on_update": 0, "on_click": 0, "on_connect": 0,
                 "on_disconnect": 0, "on_rect_select": 0, "take_uploads": 1}
#: ``host.on_click`` is the Host's click event, delivered on the worker (not viser's).
WORKER_EVENTS = {("host", "on_click")}
#: Calls that hand work to the worker: ``submit`` a job, ``request`` a map (it
#: submits a render job), ``load`` a cloud (it submits a load job).
SUBMITS = {"submit", "request", "load"}
#: Builtins a callback may call to read and convert a browser's values.
PURE = {"float", "int", "bool", "str", "tuple", "frozenset", "len", "id", "isinstance",
        "all", "any", "min", "max", "abs", "next"}
#: Methods of the camera watch (:class:`rough_viewer.app.detail.CameraWatch`): it
#: debounces camera moves, and its timers only submit level-of-detail jobs.
DEBOUNCERS = {"moved", "left"}


#: Methods that write what a browser shows or the app's state: a function a callback
#: calls (a helper of the module, reading values) calls none of them.
WRITERS = {"set", "write", "show_figure", "assign", "set_figure", "show_error", "clear_error",
           "say", "warn", "pin", "progress", "notify", "notify_client", "add_notification",
           "remove", "colour_by", "take_overlay", "give_back_overlay", "show_cloud"}


def _writes(node: ast.AST) -> list[str]:
    """Assignments to an attribute (anywhere in the target), ``with`` (a lock),
    ``global``, ``nonlocal`` and ``del`` inside ``node``."""
    found = []
    for sub in ast.walk(node):
        if isinstance(sub, (ast.Assign, ast.AugAssign, ast.AnnAssign)):
            targets = sub.targets if isinstance(sub, ast.Assign) else [sub.target]
            found += [f"line {sub.lineno}: writes {ast.unparse(t)}" for t in targets
                      if any(isinstance(e, ast.Attribute) for e in ast.walk(t))]
        elif isinstance(sub, (ast.With, ast.Global, ast.Nonlocal, ast.Delete)):
            found.append(f"line {sub.lineno}: {type(sub).__name__.lower()}")
    return found


def _body(node: ast.AST) -> list[ast.AST]:
    return [node.body] if isinstance(node, ast.Lambda) else list(node.body)  # type: ignore[attr-defined]


def _callback_problems(node: ast.AST, defs: dict[str, list[ast.AST]], seen: set[int]) -> list[str]:
    """Why the callback ``node`` (a lambda or a def) does more than submit jobs."""
    problems = []
    for part in _body(node):
        problems += _writes(part)
        problems += [p for c in ast.walk(part) if isinstance(c, ast.Call)
                     for p in _call_problems(c, defs, seen)]
    return problems


def _helper_problems(node: ast.AST, defs: dict[str, list[ast.AST]], seen: set[int]) -> list[str]:
    """Why ``node``, a function of the module a callback calls, is no mere reader."""
    if id(node) in seen:
        return []
    seen.add(id(node))
    problems = []
    for part in _body(node):
        problems += _writes(part)
        for c in ast.walk(part):
            if not isinstance(c, ast.Call):
                continue
            f = c.func
            name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
            if name in WRITERS:
                problems.append(f"line {c.lineno}: calls {ast.unparse(f)}")
            elif isinstance(f, ast.Name) and name in defs:
                problems += [p for d in defs[name] for p in _helper_problems(d, defs, seen)]
    return problems


def _call_problems(call: ast.Call, defs: dict[str, list[ast.AST]], seen: set[int]) -> list[str]:
    f = call.func
    name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
    if name in SUBMITS or (isinstance(f, ast.Attribute) and name in DEBOUNCERS):
        return []
    if isinstance(f, ast.Attribute) and name in REGISTRATIONS:
        return []  # a nested registration: its callback is checked where it is registered
    if isinstance(f, ast.Name) and name in PURE:
        return []
    root = f
    while isinstance(root, ast.Attribute):
        root = root.value
    if name[:1].isupper() or (isinstance(f, ast.Attribute) and isinstance(root, ast.Name)
                              and (root.id[:1].isupper() or root.id == "np")):
        return []  # building a value (a job, a source, a box), or numpy reading numbers
    if name in defs:  # a function or method of the feature that only reads
        return [p for d in defs[name] for p in _helper_problems(d, defs, seen)]
    return [f"line {call.lineno}: calls {ast.unparse(f)}"]


def _registered_callbacks(tree: ast.AST, defs: dict[str, list[ast.AST]]
                          ) -> Iterator[tuple[int, ast.AST | str]]:
    """(line, the callback's node or a name the feature does not define) of every
    registration in ``tree``."""
    for call in ast.walk(tree):
        if not (isinstance(call, ast.Call) and isinstance(call.func, ast.Attribute)):
            continue
        f = call.func
        if f.attr not in REGISTRATIONS or len(call.args) <= REGISTRATIONS[f.attr]:
            continue
        if isinstance(f.value, ast.Name) and (f.value.id, f.attr) in WORKER_EVENTS:
            continue
        cb = call.args[REGISTRATIONS[f.attr]]
        if isinstance(cb, ast.Lambda):
            yield call.lineno, cb
        else:
            name = cb.attr if isinstance(cb, ast.Attribute) else getattr(cb, "id", "")
            for d in defs.get(name, [ast.unparse(cb)]):
                yield call.lineno, d


def _defs(tree: ast.AST) -> dict[str, list[ast.AST]]:
    defs: dict[str, list[ast.AST]] = {}
    for d in ast.walk(tree):
        if isinstance(d, (ast.FunctionDef, ast.AsyncFunctionDef)):
            defs.setdefault(d.name, []).append(d)
    return defs


@pytest.mark.parametrize("path", FEATURE_MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_callbacks_only_submit_jobs(path: Path) -> None:
    """A callback a feature registers with viser (``on_change``, ``on_update``,
    ``on_click`` of a handle or the scene, ``on_connect``, ``on_disconnect``,
    ``on_rect_select``, ``take_uploads``) runs on viser's threads, so it only hands
    work to the worker. The rule, read from the source: the callback (a lambda, a
    function of the module, or a method of one of its classes, by name) and every
    function of the module it calls

    - assigns to no attribute (it writes no handle, no state) and has no ``with``
      (no lock), ``global``, ``nonlocal`` or ``del``;
    - calls only ``submit``, ``request`` or ``load`` (each submits a job), a class or
      one of its class methods (building a job, a source, a box), ``np.*`` (reading
      numbers), the builtins of :data:`PURE`, the camera watch's debouncer
      (:data:`DEBOUNCERS`), a nested registration (checked itself), or a reader: a
      function or method of the feature (its modules) that assigns to no attribute,
      has no ``with``, calls none of :data:`WRITERS`, and calls only readers of the
      feature.

    Reading attributes (a handle's value, the shown cloud's units) is allowed."""
    tree = ast.parse(path.read_text())
    package = path.parent if path.parent != FEATURES else None  # a feature's package
    defs = _defs(ast.Module(body=[n for p in (sorted(package.glob("*.py")) if package else [path])
                                  for n in ast.parse(p.read_text()).body], type_ignores=[]))
    problems = []
    for line, cb in _registered_callbacks(tree, defs):
        if isinstance(cb, str):
            problems.append(f"line {line}: callback {cb} is not defined in the module")
            continue
        problems += [f"callback at line {line}: {p}" for p in _callback_problems(cb, defs, set())]
    assert problems == [], f"{path.name}: " + "; ".join(problems)


def test_the_callback_check_finds_work_in_a_callback() -> None:
    tree = ast.parse(
        "def mount(host, b, f):\n"
        "    b.on_change([f.a], lambda _h: host.submit(AJob(float(f.a.value))))\n"
        "    def typed(_h):\n"
        "        f.note.content = 'x'\n"
        "        host.show_error(parse(f.box.value))\n"
        "    b.on_change([f.b], typed)\n"
        "    f.c.on_click(lambda _e: helper(f))\n"
        "def helper(f):\n"
        "    f.binding.set(f.c, 1)\n")
    defs = _defs(tree)
    found = [(line, p) for line, cb in _registered_callbacks(tree, defs)
             for p in _callback_problems(cb, defs, set())]  # type: ignore[arg-type]
    assert found == [(6, "line 4: writes f.note.content"), (6, "line 5: calls host.show_error"),
                     (6, "line 5: calls parse"), (7, "line 9: calls f.binding.set")]


#: Attributes of a viser GUI handle that change what a browser shows.
HANDLE_ATTRS = {"value", "content", "figure", "visible", "label", "options", "aspect",
                "disabled", "step", "min", "max", "hint"}


@pytest.mark.parametrize("path", FEATURE_MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_features_write_handles_through_a_binding(path: Path) -> None:
    """A feature writes a GUI handle only through a binding (``binding.set``,
    ``binding.write``, ``binding.show_figure``, which check they run on a worker) or
    inside a :class:`~rough_viewer.app.binding.Binding` subclass of its own: no
    assignment to a handle's attribute (:data:`HANDLE_ATTRS`) and no call of
    ``assign`` or ``set_figure`` elsewhere. (The shell's messages are the other
    way: ``host.say``, ``host.show_error``, ...)"""
    tree = ast.parse(path.read_text())
    inside: set[int] = set()
    for c in ast.walk(tree):
        if isinstance(c, ast.ClassDef) and any(ast.unparse(b).endswith("Binding") for b in c.bases):
            inside |= {id(n) for n in ast.walk(c)}
    found = []
    for n in ast.walk(tree):
        if id(n) in inside:
            continue
        if isinstance(n, (ast.Assign, ast.AugAssign)):
            targets = n.targets if isinstance(n, ast.Assign) else [n.target]
            found += [f"line {n.lineno}: {ast.unparse(t)} =" for t in targets
                      if isinstance(t, ast.Attribute) and t.attr in HANDLE_ATTRS
                      and isinstance(t.value, ast.Attribute)]  # x.handle.attr, not self.value
        elif isinstance(n, ast.Call) and isinstance(n.func, ast.Name) \
                and n.func.id in ("assign", "set_figure"):
            found.append(f"line {n.lineno}: {n.func.id}(...)")
    assert found == [], f"{path.name}: " + "; ".join(found)
