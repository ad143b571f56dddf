"""``npsim_core`` must never import Qt or pyvistaqt (docs/method.md §8.1): checked statically and at run time."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import npsim_core

CORE = Path(npsim_core.__file__).resolve().parent
QT = ("PySide6", "PySide2", "PyQt5", "PyQt6", "shiboken6", "shiboken2", "pyvistaqt", "qtpy", "superqt")
#: The GUI package may be imported only lazily, inside a function of a CLI command
#: (``npsim annotate`` / ``npsim gui`` open a window when they run), never at module level.
GUI = ("npsim_gui",)
FORBIDDEN = QT + GUI


def _matches(module: str, names: tuple[str, ...]) -> bool:
    return any(module == f or module.startswith(f + ".") for f in names)


def _core_files() -> list[Path]:
    files = sorted(CORE.rglob("*.py"))
    assert len(files) > 10, f"expected the npsim_core sources under {CORE}"
    return files


def find_qt_imports(source: str, filename: str = "<string>") -> list[str]:
    """``file:line module`` for every forbidden import in ``source``.

    Qt bindings and pyvistaqt are forbidden anywhere (``import``, ``from``, and
    ``importlib.import_module("...")`` / ``__import__("...")`` with a literal
    name); ``npsim_gui`` is forbidden outside function bodies.
    """
    hits: list[str] = []

    def visit(node: ast.AST, in_function: bool) -> None:
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]
        elif isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant) \
                and isinstance(node.args[0].value, str):
            fn = node.func
            fname = fn.attr if isinstance(fn, ast.Attribute) else getattr(fn, "id", "")
            if fname in ("import_module", "__import__"):
                names = [node.args[0].value]
        for n in names:
            if _matches(n, QT) or (_matches(n, GUI) and not in_function):
                hits.append(f"{filename}:{node.lineno} {n}")
        inside = in_function or isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
        for child in ast.iter_child_nodes(node):
            visit(child, inside)

    visit(ast.parse(source, filename=filename), False)
    return hits


def test_detector_catches_every_import_form():
    src = ("import PySide6.QtCore\nfrom pyvistaqt import QtInteractor\nimport os\n"
           "def f():\n    from PyQt5 import QtGui\n    importlib.import_module('PySide6.QtWidgets')\n"
           "    import npsim_gui.app\n"
           "from npsim_gui import app\nimport pyvista\n")
    hits = find_qt_imports(src, "x.py")
    assert hits == ["x.py:1 PySide6.QtCore", "x.py:2 pyvistaqt", "x.py:5 PyQt5", "x.py:6 PySide6.QtWidgets",
                    "x.py:8 npsim_gui"]


def _may_import(source: str) -> bool:
    """False when ``source`` cannot hold an import :func:`find_qt_imports` reports: every one names its
    module literally (an import statement's first name, or ``import_module``/``__import__`` with a
    string, which may spell it with escapes). Saves parsing ~1.4 MB of sources that never mention them."""
    return any(n in source for n in FORBIDDEN + ("import_module", "__import__"))


def test_no_qt_import_statements_in_core():
    hits = []
    for path in _core_files():
        source = path.read_text(encoding="utf-8")
        if _may_import(source):
            hits += find_qt_imports(source, str(path.relative_to(CORE.parent)))
    assert not hits, ("npsim_core must not import Qt/pyvistaqt (nor npsim_gui at module level):\n"
                      + "\n".join(hits))


def test_importing_every_core_module_loads_no_qt():
    modules = []
    for path in _core_files():
        rel = path.relative_to(CORE.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules.append(".".join(parts))
    code = (
        "import importlib, json, sys\n"
        f"mods = {modules!r}\n"
        "failed = {}\n"
        "for m in mods:\n"
        "    try:\n"
        "        importlib.import_module(m)\n"
        "    except Exception as exc:\n"
        "        failed[m] = repr(exc)\n"
        f"bad = sorted(k for k in sys.modules if k.split('.')[0] in {list(FORBIDDEN)!r})\n"
        "print(json.dumps({'bad': bad, 'failed': failed, 'n': len(mods)}))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                         cwd=str(CORE.parent))
    assert out.returncode == 0, out.stderr[-2000:]
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["n"] == len(modules)
    assert not res["failed"], f"core modules failed to import: {res['failed']}"
    assert not res["bad"], f"importing npsim_core loaded Qt/pyvistaqt modules: {res['bad']}"
