"""Linear-time copies of a helper's IR when numba inlines it (``inline="always"``).

Numba copies a helper's IR at every call site it inlines it into
(``numba.core.inline_closurecall.InlineWorker.inline_ir``), and it does so block by block,
each block with a fresh ``copy.deepcopy`` memo. Every variable points at the function's one
scope, which holds every variable: each block's copy copies the whole scope again, so a copy
costs blocks x variables, and it is made twice (the second only to hand back an unmutated IR
that is never mutated afterwards). For the raycaster's frame kernel, whose helpers inline
helpers, that was half of its first compilation (184 of 352 s under a profiler); with this
patch the raycaster's kernels compile in 61 s of CPU instead of 119. Upstream, numba's tracker has
"Spurious deep copies in inlining" (github.com/numba/numba/issues/8989), and numba-cuda's
"perf: Reduce copy overhead in inline passes" makes the same two changes for CUDA.

:func:`linear_inline_copies` replaces the method by the same source with two changes:

* the blocks are copied with one memo (``copy.deepcopy(the_ir.blocks)``): the copy's blocks
  share one copy of the scope, as the original's blocks share the scope;
* the IR handed back as the unmutated original is the one passed in (it is not mutated:
  the method mutates only its copy).

The compiled code is the same (the IR after inlining is the same up to the names of the
variables): the raycaster's frames and the localizer's results are the same bit for bit, and
the suite runs on the patched compiler. The patch is applied only when the method's source is
the one it was written for (numba 0.59 onwards); on any other numba nothing is changed and
compilation is only slower.
"""
from __future__ import annotations

import inspect
import textwrap

__all__ = ["linear_inline_copies"]

_PER_BLOCK = """\
        kernel_copy.blocks = {}
        for block_label, block in the_ir.blocks.items():
            new_block = copy.deepcopy(the_ir.blocks[block_label])
            kernel_copy.blocks[block_label] = new_block
        return kernel_copy
"""
_ONE_MEMO = """\
        kernel_copy.blocks = copy.deepcopy(the_ir.blocks)
        return kernel_copy
"""
_FIRST_COPY = "    callee_ir = copy_ir(callee_ir)\n"
_SECOND_COPY = "    callee_ir_original = copy_ir(callee_ir)\n"

_applied: list[bool] = []


def linear_inline_copies() -> bool:
    """Patch numba's inliner once per process (module docstring). Returns whether it is patched."""
    if _applied:
        return _applied[0]
    from numba.core import inline_closurecall

    worker = inline_closurecall.InlineWorker
    try:
        source = textwrap.dedent(inspect.getsource(worker.inline_ir))
    except (OSError, TypeError):  # no source (a frozen install): leave numba as it is
        _applied.append(False)
        return False
    if not all(source.count(part) == 1 for part in (_PER_BLOCK, _FIRST_COPY, _SECOND_COPY)):
        _applied.append(False)
        return False
    source = (source.replace(_PER_BLOCK, _ONE_MEMO)
              .replace(_FIRST_COPY, "    callee_ir_passed = callee_ir\n" + _FIRST_COPY)
              .replace(_SECOND_COPY, "    callee_ir_original = callee_ir_passed\n"))
    namespace: dict = {}
    exec(compile(source, inline_closurecall.__file__, "exec"), vars(inline_closurecall), namespace)
    worker.inline_ir = namespace["inline_ir"]
    _applied.append(True)
    return True
