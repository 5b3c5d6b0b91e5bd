"""The import graph follows the layers of docs/design.md: data flows one way.

core (arrays in, arrays out) <- analysis (tables) <- io/batch/cli, napari; nothing inside the
package imports the package's own top level; and ``import napari_pfsdm.core`` stays light.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "napari_pfsdm"

#: What each layer may import from the package (besides itself).
ALLOWED = {
    "core": {"errors"},
    "data": {"core", "errors"},
    "analysis": {"core", "data", "errors"},
    "io": {"core", "errors"},
    "batch": {"core", "analysis", "data", "io", "errors"},
    "cli": {"core", "analysis", "data", "io", "batch", "report", "saved", "errors"},
    "napari": {"core", "analysis", "data", "io", "report", "saved", "errors"},
    # the HTML report's file: the analysis' page (analysis.report) written as io writes
    "report": {"core", "analysis", "io", "errors"},
    # an analysis kept in a folder: its tables written as io writes them, its labels read
    # back from their file as batch reads movies
    "saved": {"core", "analysis", "io", "batch", "errors"},
    "__main__": {"cli"},
    "__init__": {"core", "analysis", "io", "errors"},
    "_version": set(),
    # the one exception class for input a user can fix: imports nothing, used by every layer
    "errors": set(),
}


def _layer(path: Path) -> str:
    rel = path.relative_to(SRC)
    return rel.parts[0].removesuffix(".py")


def _package_imports(text: str, rel: tuple[str, ...]) -> list[tuple[int, str]]:
    """(line, top-level part) of every import of the package in ``text``, the source of the
    module at ``rel`` (parts under src/napari_pfsdm, e.g. ("core", "descriptor.py")),
    absolute or relative; the package's own top level gives "napari_pfsdm"."""
    tree = ast.parse(text)
    here = list(rel[:-1])  # the module's package, as parts
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                if parts[0] == "napari_pfsdm":
                    out.append((node.lineno, parts[1] if len(parts) > 1 else "napari_pfsdm"))
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                parts = (node.module or "").split(".")
                if parts[0] == "napari_pfsdm":
                    out.append((node.lineno, parts[1] if len(parts) > 1 else "napari_pfsdm"))
                continue
            base = here[: len(here) - (node.level - 1)]
            parts = base + (node.module.split(".") if node.module else [])
            if parts:
                out.append((node.lineno, parts[0].removesuffix(".py")))
            else:  # "from . import x" in the package's top level: x is a module or a name
                out.extend((node.lineno, a.name) for a in node.names)
    return out


def _violations(path: Path) -> list[tuple[int, str]]:
    rel = path.relative_to(SRC).parts
    layer = _layer(path)
    text = path.read_text(encoding="utf-8")
    return [(line, target) for line, target in _package_imports(text, rel)
            if target not in (layer, "_version") and target not in ALLOWED[layer]]


MODULES = sorted(p for p in SRC.rglob("*.py"))


#: The paper's reproductions, outside the package (``pfsdm demo`` runs two of them from a
#: checkout): they use the library, as any script would, and nothing of its command line,
#: batch runs or plugin.
EXAMPLES = SRC.parents[1] / "examples"
EXAMPLES_ALLOWED = {"core", "analysis", "data", "io", "errors"}


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(SRC)))
def test_imports_follow_the_layers(path):
    assert _layer(path) in ALLOWED, f"{path.relative_to(SRC)}: a new layer, add it to ALLOWED"
    bad = _violations(path)
    assert not bad, (f"{path.relative_to(SRC)} ({_layer(path)}) imports "
                     + ", ".join(f"{t} (line {n})" for n, t in bad))


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*.py")), ids=lambda p: p.name)
def test_examples_use_the_library_only(path):
    text = path.read_text(encoding="utf-8")
    tree = ast.parse(text)
    relative = [node.lineno for node in ast.walk(tree)
                if isinstance(node, ast.ImportFrom) and node.level]
    assert not relative, f"examples/{path.name}: a script has no package (lines {relative})"
    bad = [(line, target) for line, target in _package_imports(text, ("examples", path.name))
           if target not in EXAMPLES_ALLOWED]
    assert not bad, f"examples/{path.name} imports " + ", ".join(
        f"{t} (line {n})" for n, t in bad)


def test_the_examples_are_found():
    assert {p.stem for p in EXAMPLES.glob("*.py")} >= {
        "synthetic_five_shapes", "gastruloid_report", "pixel_baseline"}


def test_the_checker_sees_forbidden_imports():
    text = "from ..analysis import features\nimport napari_pfsdm\nfrom . import sdf\n"
    found = [t for _, t in _package_imports(text, ("core", "descriptor.py"))]
    assert found == ["analysis", "napari_pfsdm", "core"]
    found = [t for _, t in _package_imports("from . import __version__\n", ("cli.py",))]
    assert found == ["__version__"]  # the top level itself: not allowed for cli


LIGHT = """
import importlib, json, sys
importlib.import_module({module!r})
print(json.dumps(sorted(m for m in {heavy!r} if m in sys.modules)))
"""


@pytest.mark.parametrize("module, heavy", [
    ("napari_pfsdm", ["pandas", "sklearn", "matplotlib", "dask", "torch", "qtpy", "napari"]),
    ("napari_pfsdm.core", ["pandas", "sklearn", "matplotlib", "dask", "torch", "qtpy"]),
    ("napari_pfsdm.analysis.features", ["sklearn", "matplotlib", "dask", "torch", "qtpy"]),
    ("napari_pfsdm.analysis.classification", ["matplotlib", "torch", "qtpy", "napari"]),
])
def test_importing_a_layer_stays_light(module, heavy):
    out = subprocess.run([sys.executable, "-c", LIGHT.format(module=module, heavy=heavy)],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout.strip().splitlines()[-1]) == []


#: Code that may write ``DataFrame.attrs``: the one carrier of a table's options.
ATTRS_WRITERS = {("core", "table_options.py")}


def _attrs_writes(text: str) -> list[int]:
    """Lines that assign ``x.attrs`` or ``x.attrs[...]`` (plain or augmented)."""
    lines = []
    for node in ast.walk(ast.parse(text)):
        targets = (node.targets if isinstance(node, ast.Assign)
                   else [node.target] if isinstance(node, ast.AugAssign | ast.AnnAssign)
                   else [])
        for t in targets:
            t = t.value if isinstance(t, ast.Subscript) else t
            if isinstance(t, ast.Attribute) and t.attr == "attrs":
                lines.append(node.lineno)
    return lines


def test_table_options_travel_through_one_helper():
    """Options ride in ``DataFrame.attrs``, which merge and concat drop: every producer goes
    through core/table_options.py instead of restoring them by hand (17 sites)."""
    found = {}
    for path in MODULES:
        rel = path.relative_to(SRC).parts
        if rel[0] == "napari" or rel in ATTRS_WRITERS:  # the plugin: its own developer's
            continue
        lines = _attrs_writes(path.read_text(encoding="utf-8"))
        if lines:
            found["/".join(rel)] = lines
    assert not found, f"hand-written DataFrame.attrs (use core.table_options): {found}"
    assert _attrs_writes("t.attrs = {}\nt.attrs['pfsdm'] = o\nx = t.attrs\n") == [1, 2]


@pytest.mark.parametrize("package", ["napari_pfsdm", "napari_pfsdm.core"])
def test_every_public_name_resolves_and_type_checkers_see_the_same(package):
    """The lazy names (core/_lazy.py) give the objects the ``TYPE_CHECKING`` imports name."""
    import importlib

    mod = importlib.import_module(package)
    tree = ast.parse(Path(mod.__file__).read_text(encoding="utf-8"))
    block = next(node for node in tree.body if isinstance(node, ast.If)
                 and getattr(node.test, "id", "") == "TYPE_CHECKING")
    static = {}
    for node in block.body:
        source = importlib.import_module("." + node.module, package)
        for alias in node.names:
            static[alias.asname or alias.name] = getattr(source, alias.name)
    public = [name for name in mod.__all__ if name != "__version__"]
    assert {name: getattr(mod, name) for name in public} == static
    assert set(mod.__all__) <= set(dir(mod))
    with pytest.raises(AttributeError, match="no attribute 'nothing_of_that_name'"):
        mod.nothing_of_that_name  # noqa: B018



def _module_graph() -> dict[str, set[str]]:
    """Every module of the package (``"analysis/features"``) and the package modules it
    imports, at the top or inside a function, relative or absolute; ``from pkg import name``
    is an edge to ``pkg/name`` when that is a module, else to ``pkg/__init__``."""
    def target(parts: list[str], names: list[str]) -> list[str]:
        out = []
        for name in names or [""]:
            sub = [*parts, name] if name else parts
            if (SRC.joinpath(*sub).with_suffix(".py")).is_file() and name:
                out.append("/".join(sub))
            elif SRC.joinpath(*parts).with_suffix(".py").is_file():
                out.append("/".join(parts))
            elif SRC.joinpath(*parts, "__init__.py").is_file():
                out.append("/".join([*parts, "__init__"]))
        return out

    graph: dict[str, set[str]] = {}
    for path in SRC.rglob("*.py"):
        rel = path.relative_to(SRC).with_suffix("").parts
        here = list(rel[:-1])
        deps: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = here[:len(here) - (node.level - 1)]
                elif (node.module or "").split(".")[0] == "napari_pfsdm":
                    node_module = node.module.split(".", 1)[1] if "." in node.module else ""
                    deps.update(target(node_module.split(".") if node_module else [],
                                       [a.name for a in node.names]))
                    continue
                else:
                    continue
                mod = (node.module or "").split(".") if node.module else []
                deps.update(target([*base, *mod], [a.name for a in node.names]))
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    parts = alias.name.split(".")
                    if parts[0] == "napari_pfsdm" and len(parts) > 1:
                        deps.update(target(parts[1:], []))
        graph["/".join(rel)] = deps - {"/".join(rel)}
    return graph


def _circle(graph: dict[str, set[str]]) -> list[str] | None:
    """One circle of ``graph`` (its modules in order, the first repeated), or None."""
    done: set[str] = set()

    def visit(node: str, stack: list[str]) -> list[str] | None:
        if node in stack:
            return [*stack[stack.index(node):], node]
        if node in done:
            return None
        for dep in sorted(graph.get(node, ())):
            found = visit(dep, [*stack, node])
            if found:
                return found
        done.add(node)
        return None

    for node in sorted(graph):
        found = visit(node, [])
        if found:
            return found
    return None


def test_the_package_imports_form_no_circle():
    """No module of the package imports, however indirectly, a module that imports it: a
    circle (the analysis dock and the plots dock importing each other; the worker pool and
    the feature code) makes the import order matter and the rooms inseparable."""
    graph = _module_graph()
    assert {"analysis/features", "io/tables", "napari/_model"} <= set(graph)
    assert "analysis/label_images" in graph["analysis/features"]
    assert _circle(graph) is None, " -> ".join(_circle(graph))
    # "from . import x" is an edge too (a circle can hide in that form)
    assert "core/distances3d" in graph["core/distances"]  # core/distances.py's form
    # the checker finds a circle hidden behind a function-level import
    graph["analysis/label_images"] = graph["analysis/label_images"] | {"analysis/features"}
    assert _circle(graph) is not None


#: A module longer than this says why in its docstring ("Its length ..."): rooms of one idea.
LONG_MODULE = 650


def test_a_long_module_says_why_it_is_long():
    long = []
    for path in sorted(SRC.rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        if text.count("\n") > LONG_MODULE and "Its length" not in (ast.get_docstring(
                ast.parse(text)) or ""):
            long.append(f"{path.relative_to(SRC)} ({text.count(chr(10))} lines)")
    assert not long, f"modules over {LONG_MODULE} lines without a reason: {long}"


def test_no_private_name_crosses_a_package():
    """A module takes from another room (core, analysis, io, batch, cli, ...) only its public
    names: an underscore name is its own room's business, free to change without a caller
    elsewhere breaking (``from ..core.distances import _x`` and ``distances._x`` alike)."""
    crossings = []
    for path in SRC.rglob("*.py"):
        rel = path.relative_to(SRC).parts
        room = rel[0].removesuffix(".py")
        modules = {}  # local name -> room of a module imported whole
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = list(rel[:-1])[:len(rel) - node.level]
                    target = base + (node.module.split(".") if node.module else [])
                elif (node.module or "").split(".")[0] == "napari_pfsdm":
                    target = node.module.split(".")[1:]
                else:
                    continue
                other = target[0].removesuffix(".py") if target else ""
                for alias in node.names:
                    if not target:  # from .. import cli: a room imported whole
                        modules[alias.asname or alias.name] = alias.name
                    elif len(target) >= 1 and (SRC.joinpath(*target, alias.name + ".py")
                                               .is_file()):
                        modules[alias.asname or alias.name] = other
                    elif (alias.name.startswith("_") and not alias.name.startswith("__")
                          and other != room):
                        crossings.append(f"{'/'.join(rel)}:{node.lineno} {alias.name}")
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                  and node.attr.startswith("_") and not node.attr.startswith("__")
                  and modules.get(node.value.id, room) != room):
                crossings.append(f"{'/'.join(rel)}:{node.lineno} {node.value.id}.{node.attr}")
    assert not crossings, crossings
