"""The package's modules import downward only: the graph of their imports (at the top of a
module and inside its functions alike) has no circle, no module imports another's private
names, a function imports no package module (LAZY lists the exceptions, with the reason), and
every import inside a function (an optional or slow dependency: SciPy, SymPy, matplotlib,
Dask) says why on its line or the line above. python/mbdk/*.py and its subpackages, read with
ast; the compiled extension (_kernel) is a leaf."""
import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "python" / "mbdk"

#: package modules a function may import lazily, and why (none may dodge a circle); none now
LAZY: dict[str, str] = {}


def _modules() -> dict:
    """Dotted name within the package ("__init__", "errors", "analysis.timing") -> path."""
    out = {}
    for path in sorted(PKG.rglob("*.py")):
        parts = list(path.relative_to(PKG).with_suffix("").parts)
        if parts[-1] == "__init__" and len(parts) > 1:
            parts = parts[:-1]
        out[".".join(parts)] = path
    out["_kernel"] = None
    return out


def _base(mods: dict, here: str, node) -> str | None:
    """The package module an ImportFrom in module `here` names ("" the package itself), or
    None for a module outside the package."""
    if node.level == 0:
        if node.module is None or not (node.module == "mbdk" or node.module.startswith("mbdk.")):
            return None
        return node.module.removeprefix("mbdk").lstrip(".")
    is_package = here == "__init__" or mods[here].name == "__init__.py"
    pkg = [] if here == "__init__" else here.split(".") if is_package else here.split(".")[:-1]
    pkg = pkg[:len(pkg) - (node.level - 1)]
    return ".".join(pkg + ([node.module] if node.module else []))


def _targets(mods: dict, here: str, node) -> list:
    """(package module, names taken from it) for each package module an import loads."""
    if isinstance(node, ast.Import):
        return [(a.name.removeprefix("mbdk").lstrip(".") or "__init__", [])
                for a in node.names if a.name == "mbdk" or a.name.startswith("mbdk.")]
    base = _base(mods, here, node)
    if base is None:
        return []

    def join(name):
        return f"{base}.{name}" if base else name
    names = [a.name for a in node.names]
    out = [(join(n), []) for n in names if join(n) in mods]     # `from . import module`
    taken = [n for n in names if join(n) not in mods]
    if taken:
        out.append((base or "__init__", taken))
    return out


def _imports():
    """(module, target, imported names, at the top?) for every import of a package module."""
    mods = _modules()
    found = []
    for here, path in mods.items():
        if path is None:
            continue
        tree = ast.parse(path.read_text())

        def visit(node, top):
            for child in ast.iter_child_nodes(node):
                if isinstance(child, (ast.Import, ast.ImportFrom)):
                    for target, names in _targets(mods, here, child):
                        found.append((here, target, names, top, child.lineno))
                elif isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                    visit(child, False)
                else:
                    visit(child, top)
        visit(tree, True)
    return mods, found


def test_the_module_graph_has_no_circle():
    mods, found = _imports()
    graph = {m: set() for m in mods}
    for here, target, _names, _top, _line in found:
        if target != here:
            graph[here].add(target)
    assert "diagnosis" in graph["simulate"] and "_kernel" in graph["codes"]   # the graph is read
    state, path = {}, []

    def walk(m):
        state[m] = "open"
        path.append(m)
        for t in sorted(graph[m]):
            assert state.get(t) != "open", "import circle: " + " -> ".join(
                path[path.index(t):] + [t])
            if t not in state:
                walk(t)
        path.pop()
        state[m] = "done"
    for m in sorted(graph):
        if m not in state:
            walk(m)


def test_no_module_imports_another_modules_private_names():
    _mods, found = _imports()
    private = [(here, line, target, n) for here, target, names, _top, line in found
               for n in names if n.startswith("_") and not n.startswith("__")]
    assert not private, private


def test_a_function_imports_a_package_module_only_for_a_heavy_optional_dependency():
    _mods, found = _imports()
    lazy = [(here, line, target) for here, target, _names, top, line in found
            if not top and target not in LAZY]
    assert not lazy, lazy


def _function_imports():
    """(module, line, source lines) for every import statement inside a function."""
    for here, path in _modules().items():
        if path is None:
            continue
        text = path.read_text()
        lines = text.splitlines()
        for fn in ast.walk(ast.parse(text)):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for node in ast.walk(fn):
                    if isinstance(node, (ast.Import, ast.ImportFrom)):
                        yield here, node.lineno, lines


def test_an_import_inside_a_function_says_why():
    found = list(_function_imports())
    assert any(here == "symbolic" for here, _line, _lines in found)     # the walk finds them
    silent = [(here, line, lines[line - 1].strip()) for here, line, lines in found
              if "#" not in lines[line - 1] and not lines[line - 2].lstrip().startswith("#")]
    assert not silent, silent
