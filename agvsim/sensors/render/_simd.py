"""Explicit vector code for the raycaster's texture filter, where LLVM's loop vectoriser cannot go.

A wall's span reads its texel column (:func:`agvsim.sensors.render._raycast_face.shade_face`)
at positions that step by a constant per row: an interpolated read at a position computed per
row, which LLVM vectorises only with gathers, and which it declines on this processor family
(AMD Zen 4's gathers are slower than scalar loads; LLVM's cost model knows it). The positions of
a few consecutive rows lie in a short window of the column, though: a window of 32 texels,
loaded as two 16-lane vectors, holds every texel that 16 consecutive samples less than 2 texels
apart read, and the AVX-512 two-table permute (``vpermi2ps``) picks each sample's texel and
its neighbour from it by lane index. No gather, no scalar load per sample.

:func:`pair_sums8` is that, for 8 rows at a time. It is used only where the processor has
AVX-512 (:data:`PERMUTE`, read from LLVM's view of the host when this module is imported);
elsewhere the kernels keep their scalar loop (the branch on :data:`PERMUTE` is resolved when
the kernel is compiled, and numba's cache is keyed by the processor's name and features, so a
cache copied to another machine is not reused there). Where the processor lacks AVX-512,
:func:`pair_sums8` still compiles, to per-lane element reads, so that a kernel holding it in a
branch never taken builds everywhere.
"""
from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ["PERMUTE", "PERMUTE_ROWS", "PERMUTE_MAX_STEP", "PERMUTE_WINDOW", "pair_sums8"]


def _host_has_avx512() -> bool:
    try:
        import llvmlite.binding as llvm

        features = llvm.get_host_cpu_features()
        return bool(features.get("avx512f", False))
    except Exception:  # noqa: BLE001 - no feature list: the scalar loop
        return False


#: whether the kernels use :func:`pair_sums8`: the processor has AVX-512
PERMUTE = _host_has_avx512()
#: rows per :func:`pair_sums8`: 16 samples, two a row
PERMUTE_ROWS = 8
#: texels one :func:`pair_sums8` may read past its window's start (the window: ``buf[base:base + 32]``)
PERMUTE_WINDOW = 32
#: the largest step between samples (texels) :func:`pair_sums8` takes: 16 samples then lie
#: within 15 x 1.99 + 1 < 31 texels of the window's start, and each one's neighbour within 32
PERMUTE_MAX_STEP = 1.99

_F32 = ir.FloatType()
_I32 = ir.IntType(32)
_I64 = ir.IntType(64)
_V16 = ir.VectorType(_F32, 16)
_VI16 = ir.VectorType(_I32, 16)
_V8 = ir.VectorType(_F32, 8)


def _splat(builder, value, vec_type):
    undef = ir.Constant(vec_type, ir.Undefined)
    one = builder.insert_element(undef, value, ir.Constant(_I32, 0))
    return builder.shuffle_vector(one, undef, ir.Constant(ir.VectorType(_I32, vec_type.count), [0] * vec_type.count))


def _pick(builder, lo, hi, index):
    """Lane ``k`` of the result: lane ``index[k]`` of ``lo`` and ``hi`` taken as one 32-lane
    table (``vpermi2ps``; per-lane element reads without AVX-512)."""
    if PERMUTE:
        permute = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_V16, [_V16, _VI16, _V16]),
                                                 "llvm.x86.avx512.vpermi2var.ps.512")
        return builder.call(permute, [lo, index, hi])
    table = builder.shuffle_vector(lo, hi, ir.Constant(ir.VectorType(_I32, 32), list(range(32))))
    out = ir.Constant(_V16, ir.Undefined)
    for k in range(16):
        lane = builder.extract_element(index, ir.Constant(_I32, k))
        out = builder.insert_element(out, builder.extract_element(table, lane), ir.Constant(_I32, k))
    return out


@intrinsic
def pair_sums8(typingctx, buf, base, offset, step, out, at):
    """``out[at + r]`` (``r = 0 .. 7``) = ``s(2 r) + s(2 r + 1)``, with ``s(k)`` the linear
    interpolation of ``buf`` at ``base + offset + k step`` (float32: ``buf[q] + (buf[q + 1] -
    buf[q]) f``, ``q`` its integer part, ``f`` the rest).

    Args:
        buf: 1-D float32 array, C-contiguous; ``buf[base:base + 32]`` must lie inside it.
        base: int64, the window's start. offset: float, ``>= 0``, the first sample's position
            in the window. step: float, ``|step| <= PERMUTE_MAX_STEP`` (texels between
            samples); every sample must lie in ``0 <= offset + k step < 31`` (k = 0..15).
        out: 1-D float32 array, C-contiguous; ``out[at:at + 8]`` written.

    Two rows of a wall's span sample its texel column twice each, a quarter of the row's step
    either side of its centre: the 16 samples of 8 rows are one arithmetic sequence, and each
    row's sum is two neighbours in it. (No bounds are checked: the caller's arithmetic
    guarantees them.)
    """
    if not (isinstance(buf, types.Array) and buf.dtype == types.float32 and buf.ndim == 1
            and isinstance(out, types.Array) and out.dtype == types.float32 and out.ndim == 1):
        return None
    sig = types.void(buf, base, offset, step, out, at)

    def codegen(context, builder, signature, args):
        buf_v, base_v, off_v, step_v, out_v, at_v = args
        src = context.make_array(signature.args[0])(context, builder, buf_v)
        dst = context.make_array(signature.args[4])(context, builder, out_v)
        base64 = context.cast(builder, base_v, signature.args[1], types.int64)
        window = builder.gep(src.data, [base64])

        def load16(k):
            ptr = builder.bitcast(builder.gep(window, [ir.Constant(_I64, k)]), _V16.as_pointer())
            return builder.load(ptr, align=4)

        lo, hi = load16(0), load16(16)
        off = _splat(builder, context.cast(builder, off_v, signature.args[2], types.float32), _V16)
        stp = _splat(builder, context.cast(builder, step_v, signature.args[3], types.float32), _V16)
        pos = builder.fadd(builder.fmul(ir.Constant(_V16, [float(k) for k in range(16)]), stp), off)
        q = builder.fptosi(pos, _VI16)  # (pos >= 0: truncation is the floor)
        frac = builder.fsub(pos, builder.sitofp(q, _V16))
        q_next = builder.add(q, ir.Constant(_VI16, [1] * 16))
        at_q, at_next = _pick(builder, lo, hi, q), _pick(builder, lo, hi, q_next)
        sample = builder.fadd(at_q, builder.fmul(builder.fsub(at_next, at_q), frac))
        undef = ir.Constant(_V16, ir.Undefined)
        even = builder.shuffle_vector(sample, undef, ir.Constant(ir.VectorType(_I32, 8), list(range(0, 16, 2))))
        odd = builder.shuffle_vector(sample, undef, ir.Constant(ir.VectorType(_I32, 8), list(range(1, 16, 2))))
        at64 = context.cast(builder, at_v, signature.args[5], types.int64)
        ptr = builder.bitcast(builder.gep(dst.data, [at64]), _V8.as_pointer())
        builder.store(builder.fadd(even, odd), ptr, align=4)
        return context.get_dummy_value()

    return sig, codegen
