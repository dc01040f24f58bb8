"""The layout rules of docs/conventions.md ("Shape", "Tests") that ruff and import-linter cannot check:
module size, no logic in a package's `__init__.py`, and a test tree that mirrors the packages."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SOURCES = {"robotexp": ROOT / "robotexp", "plugins": ROOT / "plugins", "drivers": ROOT / "drivers"}
MAX_LINES = 850
TOO_BIG_ON_PURPOSE = {"drivers/p3dx/codec.py"}     # the whole P3-DX protocol with its tables (docs/conventions.md)


def _modules() -> list[Path]:
    return sorted(p for root in SOURCES.values() for p in root.rglob("*.py"))


def test_modules_stay_under_the_size_limit() -> None:
    too_big = {p.relative_to(ROOT).as_posix(): n for p in _modules()
               if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert set(too_big) <= TOO_BIG_ON_PURPOSE, too_big


def _is_allowed_in_init(node: ast.stmt) -> bool:
    if isinstance(node, (ast.Import, ast.ImportFrom)):
        return True
    if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):     # the docstring
        return True
    if isinstance(node, (ast.Assign, ast.AnnAssign)):                       # __all__, the export tables
        value = node.value
        return isinstance(value, (ast.List, ast.Dict, ast.Tuple, ast.Constant))
    if isinstance(node, ast.If):                                            # if TYPE_CHECKING: imports
        return (isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING"
                and all(isinstance(n, (ast.Import, ast.ImportFrom)) for n in node.body))
    if isinstance(node, ast.FunctionDef):                                   # PEP 562 lazy exports only
        return node.name in ("__getattr__", "__dir__")
    return False


def test_package_inits_re_export_and_hold_no_logic() -> None:
    offenders = []
    for init in (p for p in _modules() if p.name == "__init__.py"):
        for node in ast.parse(init.read_text()).body:
            if not _is_allowed_in_init(node):
                offenders.append(f"{init.relative_to(ROOT)}:{node.lineno}")
    assert offenders == []


def test_the_test_tree_mirrors_the_packages() -> None:
    packages = {p.parent.name for p in (ROOT / "robotexp").glob("*/__init__.py")} | {"plugins", "drivers"}
    folders = {p.name for p in (ROOT / "tests").iterdir() if p.is_dir() and not p.name.startswith((".", "_"))}
    assert folders <= packages, folders - packages
    top_modules = {p.stem for p in (ROOT / "robotexp").glob("*.py") if p.stem != "__init__"}
    flat = [p.name for p in (ROOT / "tests").glob("test_*.py")
            if not any(p.stem == f"test_{m}" or p.stem.startswith(f"test_{m}_") for m in top_modules)
            and _imports_robotexp(p)]
    assert flat == [], f"tests of a package belong in tests/<package>/: {flat}"


def _imports_robotexp(path: Path) -> bool:
    """Whether a test imports robotexp's code (a flat test that does not checks the repository itself)."""
    for node in ast.walk(ast.parse(path.read_text())):
        names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                 else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
        if any(n.split(".")[0] in ("robotexp", "robotexp_plugins", "robotexp_drivers") for n in names):
            return True
    return False


def test_test_files_have_unique_names() -> None:
    names = [p.name for p in (ROOT / "tests").rglob("test_*.py")]
    assert len(names) == len(set(names)), sorted(n for n in set(names) if names.count(n) > 1)
