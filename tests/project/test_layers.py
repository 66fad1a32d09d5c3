"""The import rules of the README's folder map, checked on the source: every ``import`` of a
``fliss`` module (at module level or inside a function) read with :mod:`ast`, relative imports
resolved, and the graph searched.

* The layers import downwards only: ``hdl`` < ``protocol``, ``analysis`` < ``sim`` < ``host``.
* The host's code for a real board imports nothing from ``sim``, not even through another module.
* No import circle anywhere.
"""

import ast
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parents[2]

#: Folder of each top-level package of ``fliss``.
FOLDERS = {"hdl": "hdl", "protocol": "protocol", "analysis": "analysis", "sim": "sim",
           "host": "host", "boards": "boards", "formal": "formal"}

#: What each layer may import, besides itself.
ALLOWED = {
    "hdl": set(),
    "protocol": {"hdl"},
    "analysis": {"hdl"},
    "sim": {"hdl", "protocol", "analysis"},
    "host": {"hdl", "protocol", "analysis", "sim", "boards"},
    "boards": {"hdl"},
    "formal": {"hdl", "boards"},
}

#: The host's modules on the path of a real board: the Python API, the client and the captures.
REAL_BOARD = ["board", "client", "link", "port", "stream", "bulk", "settings", "setting_kinds",
              "units", "acquisition", "rows", "fileformat", "results", "analysis", "errors",
              "plotting", "calibration", "selftest"]


def _module_name(path):
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(["fliss", *parts])


def _modules():
    modules = {}
    for folder in FOLDERS.values():
        for path in sorted((ROOT / folder).rglob("*.py")):
            modules[_module_name(path)] = path
    return modules


def _main_guard(node):
    return (isinstance(node, ast.If) and isinstance(node.test, ast.Compare)
            and isinstance(node.test.left, ast.Name) and node.test.left.id == "__name__"
            and any(isinstance(c, ast.Constant) and c.value == "__main__"
                    for c in node.test.comparators))


def _imports(name, path, known):
    """The ``fliss`` modules ``name`` imports: for ``from X import y``, ``X.y`` if that is a
    module, else ``X``."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    tree = ast.parse(path.read_text(), str(path))
    # What runs as a script (`if __name__ == "__main__":`) is not imported with the module.
    tree.body = [node for node in tree.body if not _main_guard(node)]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[:len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base
                       for alias in node.names]
        else:
            continue
        found.update(target for target in targets if target.startswith("fliss."))
    return found


@pytest.fixture(scope="module")
def graph():
    modules = _modules()
    return {name: {target for target in _imports(name, path, modules) if target in modules}
            for name, path in modules.items()}


def _layer(module):
    return module.split(".")[1]


def test_the_graph_is_read(graph):
    # The checks below mean something only if the imports are found: a few known edges.
    assert "fliss.protocol.layout" in graph["fliss.host.client"]
    assert "fliss.hdl.delay.settings" in graph["fliss.sim.models.trivium"]
    assert "fliss.analysis.peaks" in graph["fliss.host.analysis"]


def test_layers_import_downwards(graph):
    wrong = sorted(f"{module} imports {target}" for module, targets in graph.items()
                   for target in targets
                   if _layer(target) != _layer(module)
                   and _layer(target) not in ALLOWED[_layer(module)])
    assert wrong == []


def test_the_real_board_path_imports_nothing_from_sim(graph):
    wrong = []
    for start in (f"fliss.host.{name}" for name in REAL_BOARD):
        seen, todo = {start}, [(start, (start,))]
        while todo:
            module, via = todo.pop()
            for target in sorted(graph[module] - seen):
                seen.add(target)
                if _layer(target) == "sim":
                    wrong.append(" -> ".join((*via, target)))
                else:
                    todo.append((target, (*via, target)))
    assert wrong == []


def test_no_import_circle(graph):
    # Tarjan's strongly connected components; a component of more than one module is a circle.
    index, low, stack, on_stack, circles = {}, {}, [], set(), []

    def visit(module):
        index[module] = low[module] = len(index)
        stack.append(module)
        on_stack.add(module)
        for target in graph[module]:
            if target not in index:
                visit(target)
                low[module] = min(low[module], low[target])
            elif target in on_stack:
                low[module] = min(low[module], index[target])
        if low[module] == index[module]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == module:
                    break
            if len(component) > 1:
                circles.append(sorted(component))

    for module in sorted(graph):
        if module not in index:
            visit(module)
    assert circles == []
