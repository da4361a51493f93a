"""Functions longer than a limit (default 60 lines, decorators and docstring included), as ruff
has no such rule: `python scripts/function_lengths.py [--max N] [--exclude PATH]... PATH...`;
exits 1 naming them. scripts/check runs it on every package."""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path


def long_functions(paths: list[Path], limit: int, exclude: list[Path] | None = None) -> list[str]:
    skipped = [e.resolve() for e in exclude or []]
    found = []
    for root in paths:
        for file in sorted(root.rglob("*.py") if root.is_dir() else [root]):
            if any(file.resolve().is_relative_to(e) for e in skipped):
                continue
            for node in ast.walk(ast.parse(file.read_text(encoding="utf-8"))):
                if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                    first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
                    lines = (node.end_lineno or node.lineno) - first + 1
                    if lines > limit:
                        found.append(f"{file}:{node.lineno}: {node.name} is {lines} lines (limit {limit})")
    return found


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--max", type=int, default=60)
    parser.add_argument("--exclude", type=Path, action="append", default=[],
                        help="a file or folder not to check (repeatable)")
    parser.add_argument("paths", nargs="+", type=Path)
    args = parser.parse_args()
    found = long_functions(args.paths, args.max, args.exclude)
    print("\n".join(found) or f"no function over {args.max} lines", file=sys.stderr if found else sys.stdout)
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
