"""What the tests of examples/plugins' detectors share: where they live, what they may import."""

from __future__ import annotations

import ast
import sys

from served_detector import PLUGINS

__all__ = ["ALLOWED_IMPORTS", "PLUGINS", "imports_beyond_the_rule"]
ALLOWED_IMPORTS = frozenset({"perception", "numpy", "table_objects"}) | sys.stdlib_module_names
"""table_objects: what the folder's two detectors share (examples/plugins/table_objects.py)."""


def imports_beyond_the_rule(module: str) -> set[str]:
    """What ``module`` (a file of examples/plugins) and the shared ``table_objects`` import that
    is neither ``perception``, numpy nor the standard library; a relative import fails."""
    imported = set()
    for name in (module, "table_objects.py"):
        for node in ast.walk(ast.parse((PLUGINS / name).read_text())):
            if isinstance(node, ast.Import):
                imported |= {alias.name for alias in node.names}
            elif isinstance(node, ast.ImportFrom):
                assert node.level == 0, f"{name}: a relative import on line {node.lineno}"
                imported.add(node.module)
    assert "perception.interface" in imported
    return {name for name in imported if name.partition(".")[0] not in ALLOWED_IMPORTS}
