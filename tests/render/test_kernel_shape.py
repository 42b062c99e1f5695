"""The renderer's functions stay readable (checked on the source of ``agvsim/sensors/render/``):

* none takes more than 10 parameters (``self`` and ``cls`` not counted): a kernel that needs
  more takes a record (``ray_records.py``: named tuples whose fields are documented once);
* none is longer than 80 lines (docstring included).
"""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RENDER = ROOT / "agvsim" / "sensors" / "render"
MAX_PARAMETERS = 10
MAX_LINES = 80


def _functions():
    for path in sorted(RENDER.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                yield path.relative_to(ROOT).as_posix(), node


def _parameters(fn: ast.FunctionDef) -> int:
    a = fn.args
    names = [p.arg for p in (*a.posonlyargs, *a.args, *a.kwonlyargs)] + [p.arg for p in (a.vararg, a.kwarg) if p]
    return len(names) - (1 if names and names[0] in ("self", "cls") else 0)


def test_the_renderer_is_found():
    assert sum(1 for _ in _functions()) > 100


def test_no_function_takes_more_than_ten_parameters():
    bad = [f"{rel}:{fn.lineno} {fn.name}: {_parameters(fn)}" for rel, fn in _functions()
           if _parameters(fn) > MAX_PARAMETERS]
    assert bad == [], "pass a record (ray_records.py) instead:\n" + "\n".join(bad)


def test_no_function_is_longer_than_eighty_lines():
    bad = [f"{rel}:{fn.lineno} {fn.name}: {fn.end_lineno - fn.lineno + 1} lines" for rel, fn in _functions()
           if fn.end_lineno - fn.lineno + 1 > MAX_LINES]
    assert bad == [], "split where a reader would:\n" + "\n".join(bad)
