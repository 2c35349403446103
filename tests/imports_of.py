"""The modules a Python file imports, anywhere in it (at module level or inside a function): for tests
that keep a generator apart from what it tests."""

from __future__ import annotations

import ast
from pathlib import Path


def imported_modules(path):
    """Every module name ``path`` imports (``import a.b``: ``a.b``; ``from a import b``: ``a`` and ``a.b``)."""
    names = []
    for node in ast.walk(ast.parse(Path(path).read_text())):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            names += [node.module or ""] + [f"{node.module}.{a.name}" for a in node.names]
    return names
