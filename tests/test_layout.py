"""The layout's promises (issue 30): the core imports no web code, the CLI's own commands do not
import the service, and the service's modules import each other without a circle."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

from tests.helpers import REPO


def _modules_after(code: str) -> set[str]:
    """The top-level packages imported once ``code`` has run, in a fresh interpreter."""
    probe = f"{code}\nimport sys\nprint(' '.join(sorted({{m.split('.')[0] for m in sys.modules}})))"
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, cwd=REPO,
                         timeout=300, check=True)
    return set(run.stdout.split())


def test_the_core_imports_no_web_code() -> None:
    loaded = _modules_after("import pkgutil, importlib, synth_core\n"
                            "for m in pkgutil.walk_packages(synth_core.__path__, 'synth_core.'):\n"
                            "    importlib.import_module(m.name)")
    assert not loaded & {"service", "api_schemas", "fastapi", "starlette", "pydantic", "uvicorn"}


def test_the_cli_makes_a_herd_without_importing_the_service(tmp_path: Path) -> None:
    out = tmp_path / "herd.npz"
    args = ["crowd-sim", "--characters", "2", "--frames", "20", "--out", str(out)]
    loaded = _modules_after(f"from quadsynth.cli import main\nmain({args!r})")
    assert out.exists() and "service" not in loaded and "fastapi" not in loaded


def _imports(file: Path, package: str) -> set[str]:
    """The ``package`` modules ``file`` imports (those for type checking too: a circle there is
    one a reader follows all the same)."""
    found = set()
    for node in ast.walk(ast.parse(file.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith(package):
            found.add(node.module)
            found.update(f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith(package))
    return found


def test_the_service_modules_import_each_other_without_a_circle() -> None:
    files = {".".join(f.relative_to(REPO).with_suffix("").parts).removesuffix(".__init__"): f
             for f in (REPO / "service").rglob("*.py")}
    graph = {name: _imports(f, "service") & set(files) - {name} for name, f in files.items()}
    done: set[str] = set()

    def visit(name: str, path: tuple[str, ...]) -> None:
        assert name not in path, f"import circle: {' -> '.join((*path, name))}"
        if name not in done:
            for nxt in sorted(graph[name]):
                visit(nxt, (*path, name))
            done.add(name)

    for name in sorted(graph):
        visit(name, ())


MAX_MODULE_LINES = 500  # issue 30: small modules named for what they hold
MAX_FUNCTION_LINES = 60  # scripts/function_lengths.py's limit, which scripts/check runs


def test_no_module_is_over_500_lines() -> None:
    sizes = {str(f.relative_to(REPO)): len(f.read_text(encoding="utf-8").splitlines())
             for package in ("synth_core", "service", "api_schemas", "quadsynth")
             for f in sorted((REPO / package).rglob("*.py"))}
    assert sizes and {f: n for f, n in sizes.items() if n > MAX_MODULE_LINES} == {}


def test_no_function_is_over_60_lines() -> None:
    """The project's function length (scripts/function_lengths.py: decorators and docstring in):
    scripts/check printed it but the suite did not fail on it, and a render function went over."""
    sys.path.insert(0, str(REPO / "scripts"))
    try:
        from function_lengths import long_functions
    finally:
        sys.path.remove(str(REPO / "scripts"))
    packages = [REPO / p for p in ("synth_core", "service", "quadsynth", "tests", "api_schemas")]
    assert long_functions(packages, MAX_FUNCTION_LINES) == []
