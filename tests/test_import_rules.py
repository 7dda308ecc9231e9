"""ARCHITECTURE.md's import rules, enforced on the source: data flows one way and only the command layer prints.

* ``converters/`` (``a5mi.converters``) and ``plugins/`` (``a5mi.plugins``) never import each other, the
  command layer (``a5mi.cli``, ``a5mi.commands``) or the renderer's driver; from ``a5mi`` they take only the
  leaf modules.
* the leaf modules (SPEC constants, options, image I/O, errors) import no other ``a5mi`` module but leaves;
* the libraries of ``a5mi/`` never import the command layer, and the command layer imports no plugin module;
* no module of the whole package imports itself back through others, and the plugin folders are layered;
* the modules of ``converters/`` import each other without cycles (counting imports inside functions and under
  ``TYPE_CHECKING``): the grammar's layers are errors -> lexer -> tokens -> model -> builders -> rules;
* nothing outside ``a5mi/cli/`` and ``a5mi/commands/`` calls ``print`` or writes to ``sys.stdout`` / ``sys.stderr``.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process

ROOT = Path(__file__).resolve().parent.parent
#: folder -> its package name
PACKAGES = {"a5mi": "a5mi", "converters": "a5mi.converters", "plugins": "a5mi.plugins"}
#: The ``a5mi`` modules every layer may import (standard library, numpy and OpenImageIO only, and each other).
LEAVES = frozenset({"a5mi", "a5mi.spec", "a5mi.render.options", "a5mi.platform", "a5mi.platform.imageio",
                    "a5mi.platform.errors",
                    "a5mi.platform.interrupts", "a5mi.platform.resources", "a5mi.vecmath32", "a5mi.platform.arrays",
                    "a5mi.platform.paths", "a5mi.platform.loading"})


def _sources(folder: str) -> list[Path]:
    return sorted((ROOT / folder).rglob("*.py"))


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT)
    parts = [PACKAGES[rel.parts[0]], *rel.parts[1:]]
    name = ".".join(parts)[: -len(".py")]
    return name[: -len(".__init__")] if name.endswith(".__init__") else name


def _package(path: Path) -> str:
    return _module_name(path) if path.name == "__init__.py" else _module_name(path).rpartition(".")[0]


def _from_module(node: ast.ImportFrom, package: str) -> str:
    """The absolute module of ``from ... import``, relative levels resolved against ``package``."""
    if not node.level:
        return node.module or ""
    base = package.split(".")[: len(package.split(".")) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def _imports(path: Path) -> set[str]:
    """Every ``a5mi...`` module ``path`` imports (absolute and relative), at any depth of the code."""
    package = _package(path)
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            module = _from_module(node, package)
            names = [module] + [f"{module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        out |= {n for n in names if n == "a5mi" or n.startswith("a5mi.")}
    return out


def _is(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def _allowed_from(module: str, own: str) -> bool:
    """For converters/plugins: own package, or a leaf module (``from a5mi.spec import TMIN`` counts as
    ``a5mi.spec`` and ``a5mi.spec.TMIN``)."""
    return _is(module, own) or module in LEAVES or module.rpartition(".")[0] in LEAVES - {"a5mi"}


@pytest.mark.parametrize(("folder", "own"), [("converters", "a5mi.converters"), ("plugins", "a5mi.plugins")])
def test_converters_and_plugins_import_only_themselves_and_the_leaves(folder: str, own: str) -> None:
    for path in _sources(folder):
        bad = {m for m in _imports(path) if not _allowed_from(m, own)}
        bad -= {"a5mi.__version__", "a5mi.data_dir", "a5mi.cache_dir"}  # a5mi/__init__ is a leaf too
        assert not bad, f"{path.relative_to(ROOT)} imports {sorted(bad)}"


def test_leaf_modules_import_only_leaves() -> None:
    for name in sorted(LEAVES):
        folder = ROOT / name.replace(".", "/")
        path = folder / "__init__.py" if folder.is_dir() else folder.with_suffix(".py")
        bad = {m for m in _imports(path) if m not in LEAVES and m.rpartition(".")[0] not in LEAVES}
        assert not bad, f"{path.relative_to(ROOT)} imports {sorted(bad)}"


def _command_layer(module: str) -> bool:
    return _is(module, "a5mi.cli") or _is(module, "a5mi.commands")


def test_libraries_never_import_the_command_layer() -> None:
    for path in [*_sources("a5mi"), *_sources("converters"), *_sources("plugins")]:
        if _command_layer(_module_name(path)) or _module_name(path) in ("a5mi.__main__", "a5mi.mitsuba", "a5mi.entry"):
            continue
        bad = {m for m in _imports(path) if _command_layer(m)}
        assert not bad, f"{path.relative_to(ROOT)} imports the command layer {sorted(bad)}"


def test_the_command_layer_reaches_into_no_plugin() -> None:
    """Commands go through the libraries (:mod:`a5mi.render`, :mod:`a5mi.trace`, ...): a plugin's module is
    the plugins' own business, registered by :func:`a5mi.plugins.register_all`."""
    for path in [*_sources("a5mi/cli"), *_sources("a5mi/commands")]:
        bad = {m for m in _imports(path) if _is(m, "a5mi.plugins")}
        assert not bad, f"{path.relative_to(ROOT)} imports plugin modules {sorted(bad)}"


def test_only_the_command_layer_prints() -> None:
    for path in [*_sources("a5mi"), *_sources("converters"), *_sources("plugins")]:
        if _command_layer(_module_name(path)):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "print":
                pytest.fail(f"{path.relative_to(ROOT)}:{node.lineno} calls print")
            if (isinstance(node, ast.Attribute) and node.attr in ("stdout", "stderr")
                    and isinstance(node.value, ast.Name) and node.value.id == "sys"):
                pytest.fail(f"{path.relative_to(ROOT)}:{node.lineno} uses sys.{node.attr}")


def test_the_rules_see_real_imports() -> None:
    """The checker itself: relative and absolute imports are resolved (a broken checker passes everything)."""
    assert "a5mi.cli.app" in _imports(ROOT / "a5mi/cli/__init__.py")
    assert any(_is(m, "a5mi.plugins") for m in _imports(ROOT / "plugins/integrators/whitted/integrator.py"))
    assert any(_is(m, "a5mi.converters") for m in _imports(ROOT / "converters/a5_parser.py"))


def _module_edges(source: str, package: str, modules: set[str]) -> set[str]:
    """The ``modules`` that ``source`` (a module of ``package``) imports, at any depth of its code: module level,
    inside functions, under ``if TYPE_CHECKING``. ``from . import x`` is an edge to ``x``, not to the package."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            module = _from_module(node, package)
            out |= {f"{module}.{a.name}" if f"{module}.{a.name}" in modules else module for a in node.names}
        elif isinstance(node, ast.Import):
            for a in node.names:
                parts = a.name.split(".")
                out |= {".".join(parts[:k]) for k in range(1, len(parts) + 1)}
    return out & modules


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle of ``graph`` (module -> modules it imports) as ``[a, b, ..., a]``, or None."""
    state: dict[str, int] = {}  # 1 on the current path, 2 done
    path: list[str] = []

    def visit(m: str) -> list[str] | None:
        state[m] = 1
        path.append(m)
        for n in sorted(graph.get(m, ())):
            if state.get(n) == 1:
                return path[path.index(n):] + [n]
            if n not in state and (found := visit(n)) is not None:
                return found
        path.pop()
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state and (found := visit(m)) is not None:
            return found
    return None


def test_converters_import_graph_is_acyclic() -> None:
    """ARCHITECTURE.md's one-way data flow inside ``converters/``: no module imports one that imports it back,
    directly or through others, by any import (module level, function level, ``TYPE_CHECKING``)."""
    paths = _sources("converters")
    modules = {_module_name(p) for p in paths}
    graph = {_module_name(p): _module_edges(p.read_text(encoding="utf-8"), _package(p), modules) - {_module_name(p)}
             for p in paths}
    assert graph["a5mi.converters.a5_parser"] >= {"a5mi.converters.tokens", "a5mi.converters.ext_parser",
                                                  "a5mi.converters.keyframes"}  # the checker sees real edges
    # the token stream is a leaf of the grammar: it knows the lexer and the errors, no rule of any block
    assert graph["a5mi.converters.tokens"] <= {"a5mi.converters.lexer", "a5mi.converters.errors"}
    cycle = _cycle(graph)
    assert cycle is None, "import cycle among converters: " + " -> ".join(cycle or [])


def _whole_graph() -> dict[str, set[str]]:
    paths = [*_sources("a5mi"), *_sources("converters"), *_sources("plugins")]
    modules = {_module_name(p) for p in paths}
    return {_module_name(p): _module_edges(p.read_text(encoding="utf-8"), _package(p), modules) - {_module_name(p)}
            for p in paths}


def test_the_whole_package_import_graph_is_acyclic() -> None:
    """No module of a5mi (``a5mi/``, ``converters/``, ``plugins/``) imports one that imports it back, directly or
    through others, by any import: module level, inside functions, under ``TYPE_CHECKING``."""
    graph = _whole_graph()
    assert "a5mi.cli.streams" in graph["a5mi.cli.progress"]  # the checker sees real edges
    cycle = _cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def _plugin_family(module: str) -> str | None:
    """The folder of :mod:`a5mi.plugins` that ``module`` lives in (``a5mi.plugins.kernel``,
    ``a5mi.plugins.integrators.photon``; a loose module is its own family)."""
    parts = module.split(".")
    if module.startswith("a5mi.plugins.integrators."):
        return ".".join(parts[:4])
    if module.startswith("a5mi.plugins.") and len(parts) > 3:
        return ".".join(parts[:3])
    return module if module.startswith("a5mi.plugins.") else None


def test_the_plugin_families_import_each_other_without_cycles() -> None:
    """ARCHITECTURE.md's plugin layers, by folder: a library never imports its clients (the kernel imports no
    integrator, media import no kernel), so the graph of the plugin folders is acyclic too."""
    graph: dict[str, set[str]] = {}
    for module, edges in _whole_graph().items():
        if (family := _plugin_family(module)) is None:
            continue
        graph.setdefault(family, set()).update(f for e in edges if (f := _plugin_family(e)) not in (None, family))
    assert "a5mi.plugins.kernel" in graph["a5mi.plugins.integrators.whitted"]  # the checker sees real edges
    assert not {f for f in graph["a5mi.plugins.kernel"] if f.startswith("a5mi.plugins.integrators")}
    cycle = _cycle(graph)
    assert cycle is None, "import cycle between plugin folders: " + " -> ".join(cycle or [])


def test_the_cycle_finder_sees_function_level_and_type_checking_imports() -> None:
    """The checker itself, on made-up modules: a cycle closed by an import inside a function or under
    ``TYPE_CHECKING`` is found; a chain is not a cycle."""
    pkg = "a5mi.converters"
    modules = {f"{pkg}.a", f"{pkg}.b", f"{pkg}.c"}
    sources = {"a": "from . import b\n",
               "b": "def f():\n    from .c import x\n",
               "c": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import a5mi.converters.a\n"}
    graph = {f"{pkg}.{k}": _module_edges(v, pkg, modules) for k, v in sources.items()}
    assert graph == {f"{pkg}.a": {f"{pkg}.b"}, f"{pkg}.b": {f"{pkg}.c"}, f"{pkg}.c": {f"{pkg}.a"}}
    assert _cycle(graph) == [f"{pkg}.a", f"{pkg}.b", f"{pkg}.c", f"{pkg}.a"]
    graph[f"{pkg}.c"] = set()
    assert _cycle(graph) is None


def test_spec_constants_have_one_home() -> None:
    """TMIN, MIRROR_THRESHOLD, FRESNEL_MODES, CUBE_FACES and IMAGE_EXTENSIONS are assigned only in a5mi/spec.py."""
    names = {"TMIN", "MIRROR_THRESHOLD", "FRESNEL_MODES", "CUBE_FACES", "IMAGE_EXTENSIONS"}
    for path in [*_sources("a5mi"), *_sources("converters"), *_sources("plugins")]:
        if path == ROOT / "a5mi" / "spec.py":
            continue
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(
                node, ast.AnnAssign) else []
            defined = {t.id for t in targets if isinstance(t, ast.Name)}
            assert not defined & names, f"{path.relative_to(ROOT)} defines {sorted(defined & names)}"


def test_describe_reads_every_file_without_importing_mitsuba(scenes_dir: Path) -> None:
    """The scene prologue (parse, describe: every file read and checked) runs before the JIT starts."""
    code = ("import sys\nfrom a5mi.converters.a5_parser import parse_file\n"
            "from a5mi.converters.describe import describe\n"
            "from a5mi.converters import materials, to_mitsuba, to_xml\n"
            f"d = describe(parse_file({str(scenes_dir / 'scene11_cube.txt')!r}), stock=True)\n"
            "assert d.background.faces and d.shapes, d\n"
            "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('mitsuba', 'drjit'))\n"
            "assert not bad, bad\n")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


def test_every_module_is_under_450_lines() -> None:
    """ARCHITECTURE.md "Module sizes": each module of a5mi/, plugins/ and converters/ owns one step and stays
    under 450 lines."""
    long = {str(p.relative_to(ROOT)): n for folder in ("a5mi", "plugins", "converters")
            for p in sorted((ROOT / folder).rglob("*.py")) if (n := len(p.read_text().splitlines())) >= 450}
    assert long == {}
