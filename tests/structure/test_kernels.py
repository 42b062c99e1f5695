"""The localizer's compiled kernels assign no array to a slice (checked on the source).

``dst[a:b] = src`` with an array ``src`` makes numba compile a shape check whose error
message is built at run time (~1,700 LLVM instructions), linked into every top-level
kernel whose call tree has one; a kernel loaded from numba's cache keeps its LLVM module
in memory, so each such kernel costs an env process about 0.5 MB more (the memory floor,
BENCHMARKS.md). The kernels copy with :mod:`localizer._kernels.arrays` instead; a scalar
(``dst[:] = 0.0``, ``np.inf``) has no shape to check.
"""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: photometric's refinement solves with np.linalg.solve, whose numba implementation has the
#: same shape check: its slice assignments cost nothing more (photometric_select: its pixel selection)
EXEMPT = {"localizer/_kernels/photometric.py", "localizer/_kernels/photometric_select.py"}
MODULES = sorted([*(ROOT / "localizer" / "_kernels").glob("*.py"), ROOT / "localizer" / "smallmat.py"])


def _scalar(node: ast.expr) -> bool:
    """A literal number or bool, ``-literal``, or a constant attribute such as ``np.inf``."""
    if isinstance(node, ast.UnaryOp):
        node = node.operand
    return isinstance(node, (ast.Constant, ast.Attribute))


def _sliced(target: ast.expr) -> bool:
    if not isinstance(target, ast.Subscript):
        return False
    index = target.slice.elts if isinstance(target.slice, ast.Tuple) else [target.slice]
    return any(isinstance(i, ast.Slice) for i in index)


def _compiled(fn: ast.FunctionDef) -> bool:
    names = {d.id if isinstance(d, ast.Name) else getattr(d, "attr", "") for d in fn.decorator_list}
    return bool(names & {"jit", "inline", "fast_jit", "fast_inline", "njit"})


def test_kernels_assign_no_array_to_a_slice():
    assert len(MODULES) > 10
    bad = []
    for path in MODULES:
        rel = path.relative_to(ROOT).as_posix()
        if rel in EXEMPT:
            continue
        for fn in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not (isinstance(fn, ast.FunctionDef) and _compiled(fn)):
                continue
            for node in ast.walk(fn):
                if isinstance(node, ast.Assign) and any(_sliced(t) for t in node.targets) and not _scalar(node.value):
                    bad.append(f"{rel}:{node.lineno}: {ast.unparse(node)}")
    assert bad == [], "copy with localizer._kernels.arrays (copy, copy_rows, fill) instead:\n" + "\n".join(bad)
