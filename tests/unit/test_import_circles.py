"""No import circle anywhere in src/: between folders (lint-imports' layers) and inside them.

Every import counts, wherever it stands: at the top, inside a function, under `if TYPE_CHECKING:`.
A circle hidden in a function-level import still ties the modules together (neither can be
understood, tested or moved without the other); its cure is to move the shared definition."""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src"


def modules(src: Path) -> dict[str, Path]:
    """Dotted name → file of every module under src (a package is its __init__.py)."""
    out = {}
    for path in sorted(src.rglob("*.py")):
        parts = list(path.relative_to(src).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _known(name: str, known: dict[str, Path]) -> str | None:
    """The module an imported dotted name lands in (a name from a module counts as the module)."""
    while name and name not in known:
        name = name.rpartition(".")[0]
    return name or None


def import_graph(src: Path) -> dict[str, set[str]]:
    """Module → the modules of src it imports, from every import statement in it (any depth)."""
    known = modules(src)
    graph: dict[str, set[str]] = defaultdict(set)
    for name, path in known.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[: len(package.split(".")) - node.level + 1]
                    origin = ".".join(base + ([node.module] if node.module else []))
                else:
                    origin = node.module or ""
                targets = [f"{origin}.{a.name}" for a in node.names]
            for target in targets:
                module = _known(target, known)
                if module is not None and module != name:
                    graph[name].add(module)
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One shortest circle per group of modules that import each other (Tarjan's strongly connected
    components, then a breadth-first search inside each): [a, b, ..., a]."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[set[str]] = []

    def visit(v: str) -> None:  # recursion depth is bounded by the number of modules (a few hundred)
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.add(w)
                if w == v:
                    break
            if len(group) > 1:
                groups.append(group)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    found = []
    for group in groups:
        start = min(group)
        came_from: dict[str, str] = {}
        frontier = [start]
        while frontier and start not in came_from:
            nxt = []
            for v in frontier:
                for w in sorted(graph[v] & group):
                    if w not in came_from:
                        came_from[w] = v
                        nxt.append(w)
            frontier = nxt
        path = [start]
        while came_from[path[-1]] != start:
            path.append(came_from[path[-1]])
        found.append([start] + path[::-1])
    return sorted(found)


def test_src_has_no_import_circle():
    found = circles(import_graph(SRC))
    assert not found, "import circles in src/ (move the shared definition to a module both can import):\n" + \
        "\n".join(" -> ".join(c) for c in found)


def _package(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def test_a_circle_through_a_function_level_import_is_found_and_named(tmp_path):
    src = _package(tmp_path, {
        "pkg/__init__.py": "",
        "pkg/a.py": "from pkg.b import g\n",
        "pkg/b.py": "from . import c\ndef g():\n    pass\n",
        "pkg/c.py": "def f():\n    from pkg.a import g  # inside a function\n",
        "pkg/d.py": "import pkg.a\n",  # imports into the circle, is not part of it
    })
    assert circles(import_graph(src)) == [["pkg.a", "pkg.b", "pkg.c", "pkg.a"]]


def test_a_type_checking_import_and_a_folder_inside_a_folder_count(tmp_path):
    src = _package(tmp_path, {
        "pkg/__init__.py": "",
        "pkg/io/__init__.py": "",
        "pkg/io/reader.py": "from pkg.model import Model\n",
        "pkg/model.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg.io.reader import read\n",
    })
    assert circles(import_graph(src)) == [["pkg.io.reader", "pkg.model", "pkg.io.reader"]]


def test_modules_that_import_one_way_make_no_circle(tmp_path):
    src = _package(tmp_path, {
        "pkg/__init__.py": "",
        "pkg/model.py": "X = 1\n",
        "pkg/io/__init__.py": "",
        "pkg/io/reader.py": "from ..model import X\nimport pkg.model as m\n",
    })
    assert circles(import_graph(src)) == []
