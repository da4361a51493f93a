"""synth_core's modules import each other without a circle (TYPE_CHECKING imports included) and
never import another module's private names."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "synth_core"


def module_imports() -> dict[str, set[tuple[str, str]]]:
    """Per module, the (module, name) pairs it imports from synth_core (name "" for a module)."""
    names = {".".join(p.relative_to(ROOT.parent).with_suffix("").parts).removesuffix(".__init__"): p
             for p in ROOT.rglob("*.py")}
    out: dict[str, set[tuple[str, str]]] = {}
    for name, path in names.items():
        found = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("synth_core"):
                for alias in node.names:
                    sub = f"{node.module}.{alias.name}"
                    found.add((sub, "") if sub in names else (node.module, alias.name))
            elif isinstance(node, ast.Import):
                found |= {(a.name, "") for a in node.names if a.name in names}
        out[name] = found
    return out


def test_no_import_circle() -> None:
    graph = {m: {d for d, _ in deps if d != m} for m, deps in module_imports().items()}
    state: dict[str, int] = {}  # 1: on the path, 2: done

    def visit(m: str, path: list[str]) -> None:
        state[m] = 1
        for d in sorted(graph[m]):
            if state.get(d) == 1:
                raise AssertionError("import circle: " + " -> ".join([*path, m, d][[*path, m].index(d):]))
            if d in graph and d not in state:
                visit(d, path + [m])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [])


def test_no_private_name_imported_across_modules() -> None:
    private = sorted((m, f"{d}.{n}") for m, deps in module_imports().items() for d, n in deps
                     if n.startswith("_") and not n.startswith("__"))
    assert private == []
