"""No function of the product code (``localizer/``, ``agvsim/``, ``envs/``) takes more than 10
parameters (``self`` and ``cls`` not counted; ``*args`` and ``**kwargs`` one each): a function,
compiled kernel or not, that needs more takes a record (a named tuple or a structured array
whose fields are documented once, as in ``localizer/_kernels/records.py``)."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PRODUCT = ("localizer", "agvsim", "envs")
MAX_PARAMETERS = 10


def _functions():
    for package in PRODUCT:
        for path in sorted((ROOT / package).rglob("*.py")):
            if ".venv" in path.parts or "__pycache__" in path.parts:
                continue
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                    yield path.relative_to(ROOT).as_posix(), node


def _parameters(fn) -> int:
    a = fn.args
    names = [p.arg for p in (*a.posonlyargs, *a.args, *a.kwonlyargs)] + [p.arg for p in (a.vararg, a.kwarg) if p]
    return len(names) - (1 if names and names[0] in ("self", "cls") else 0)


def test_the_product_code_is_found():
    files = {rel.split("/")[0] for rel, _ in _functions()}
    assert files == set(PRODUCT)
    assert sum(1 for _ in _functions()) > 1000


def test_the_count_sees_every_kind_of_parameter():
    fn = ast.parse("def f(self, a, /, b, *c, d, **e): pass").body[0]
    assert _parameters(fn) == 5
    wide = ast.parse(f"def g({', '.join(f'p{i}' for i in range(MAX_PARAMETERS + 1))}): pass").body[0]
    assert _parameters(wide) > MAX_PARAMETERS


def test_no_function_takes_more_than_ten_parameters():
    bad = [f"{rel}:{fn.lineno} {getattr(fn, 'name', 'lambda')}: {_parameters(fn)}" for rel, fn in _functions()
           if _parameters(fn) > MAX_PARAMETERS]
    assert bad == [], "pass a record (localizer/_kernels/records.py) instead:\n" + "\n".join(bad)
