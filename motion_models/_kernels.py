"""Numba kernels shared by the motion models, and their plain numpy references.

    from motion_models._kernels import move_with_noise, move_drawing_noise, bit_generator_handle, draw_uniforms

Kernels take pre-drawn variates (drawn from the filter's one Generator by `draw_variates`), so a kernel is a
deterministic function of its inputs and its numpy twin reproduces it from the same variates. (Passing the
Generator itself into numba costs about 10 µs of unboxing per call, more than the whole kernel at N = 100.)

A kernel may instead draw uniforms itself from the Generator's bit generator (`bit_generator_handle`,
`next_double`, `draw_uniforms`): the same numbers, in the same order, as `rng.random()` would give, without
an array that grows with N, a pass over it, or the Python call that fills it; numpy's PCG64 (the default)
is stepped in the kernel, eight independent steps at a time, and `parallel_uniforms` lets threads draw
their chunks of the same stream (jumping ahead). `move_drawing_noise` draws so; its results equal
`move_with_noise` on `draw_variates(rng, n, False)` bit for bit. `move_chunked` spreads the particles over
threads (the same poses), and `move_range_fast` is the opt-in fast-math variant (poses to rounding).
A heading's cos and sin come from `sincos`, a branch-free polynomial that vectorizes and gives the same bits on
every machine (libm's vary with the C library), not from libm.
"""
import ctypes
import math

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from field.angles import wrap_angles

SQRT3 = math.sqrt(3.0)
TWO_PI = 2.0 * math.pi


@numba.njit(cache=True, inline="always")
def wrap(a):
    """`field.angles.wrap_angle`, bit for bit (the floor of the same quotient kept as a float: no conversion to
    an integer and back), written with selects so that loops over particles vectorize."""
    r = a - TWO_PI * np.floor((a + math.pi) / TWO_PI)
    r = r + TWO_PI if r <= -math.pi else r
    return r - TWO_PI if r > math.pi else r


def draw_variates(rng, n: int, gaussian: bool, out: np.ndarray | None = None) -> np.ndarray:
    """The (n, 3) variates `move_with_noise` consumes: standard normals, or uniforms on [0, 1).

    With `out` (a float64 array of at least n rows, kept across steps) the variates are written into its first
    n rows, the same numbers as a fresh array would hold, and that view is returned.
    """
    if out is None:
        return rng.standard_normal((n, 3)) if gaussian else rng.random((n, 3))
    view = out[:n]
    if gaussian:
        rng.standard_normal(out=view)
    else:
        rng.random(out=view)
    return view


# -- drawing in a kernel ------------------------------------------------------------------------------------------
PCG64_INLINE = 0      # the `function` of a handle whose generator is numpy's PCG64, stepped in the kernel itself


def bit_generator_handle(rng: np.random.Generator) -> tuple[int, int]:
    """(function, state) for drawing `rng`'s uniforms in a kernel (`next_double`, `draw_uniforms`).

    function is the address of the bit generator's next_double, or PCG64_INLINE for numpy's PCG64 (the
    default generator), whose steps the kernels take themselves, eight at a time; state is the address of
    the bit generator's state. Either way a kernel draws the numbers `rng.random()` would return, in the same
    order, and leaves the generator where `rng` would be. Valid while the bit generator lives (keep a
    reference to `rng`); setting `rng.bit_generator.state` keeps both addresses.
    """
    bit_generator = rng.bit_generator
    interface = bit_generator.ctypes
    if type(bit_generator) is np.random.PCG64 and _pcg64_layout_ok():
        return PCG64_INLINE, interface.state_address
    return ctypes.cast(interface.next_double, ctypes.c_void_p).value, interface.state_address


@intrinsic
def _call_next_double(typingctx, function, state):
    """One uniform from a bit generator's next_double function (address) and state (address)."""
    signature = types.float64(types.intp, types.intp)

    def codegen(context, builder, sig, args):
        void_pointer = ir.IntType(8).as_pointer()
        function_type = ir.FunctionType(ir.DoubleType(), [void_pointer])
        callee = builder.inttoptr(args[0], function_type.as_pointer())
        return builder.call(callee, [builder.inttoptr(args[1], void_pointer)])

    return signature, codegen


@intrinsic
def _load_u64(typingctx, address):
    signature = types.uint64(types.intp)

    def codegen(context, builder, sig, args):
        return builder.load(builder.inttoptr(args[0], ir.IntType(64).as_pointer()))

    return signature, codegen


@intrinsic
def _store_u64(typingctx, address, value):
    signature = types.void(types.intp, types.uint64)

    def codegen(context, builder, sig, args):
        builder.store(args[1], builder.inttoptr(args[0], ir.IntType(64).as_pointer()))
        return context.get_dummy_value()

    return signature, codegen


@intrinsic
def _mul_add_128(typingctx, a_hi, a_lo, b_hi, b_lo, c_hi, c_lo):
    """(a·b + c) mod 2¹²⁸ on 128-bit numbers given as (high, low) uint64 halves; returns (high, low)."""
    u64 = types.uint64
    signature = types.UniTuple(u64, 2)(u64, u64, u64, u64, u64, u64)

    def codegen(context, builder, sig, args):
        i64, i128 = ir.IntType(64), ir.IntType(128)
        shift = ir.Constant(i128, 64)

        def join(high, low):
            return builder.or_(builder.shl(builder.zext(high, i128), shift), builder.zext(low, i128))

        r = builder.add(builder.mul(join(args[0], args[1]), join(args[2], args[3])), join(args[4], args[5]))
        high = builder.trunc(builder.lshr(r, shift), i64)
        return context.make_tuple(builder, sig.return_type, (high, builder.trunc(r, i64)))

    return signature, codegen


@intrinsic
def _pcg64_double(typingctx, high, low):
    """PCG64's output (XSL-RR) of a state, as numpy's next_double turns it into a uniform on [0, 1)."""
    signature = types.float64(types.uint64, types.uint64)

    def codegen(context, builder, sig, args):
        i64 = ir.IntType(64)
        high, low = args
        rotate = builder.lshr(high, ir.Constant(i64, 58))
        rotr = builder.module.declare_intrinsic("llvm.fshr", [i64], ir.FunctionType(i64, [i64, i64, i64]))
        x = builder.xor(high, low)
        word = builder.call(rotr, [x, x, rotate])
        mantissa = builder.sitofp(builder.lshr(word, ir.Constant(i64, 11)), ir.DoubleType())   # < 2⁵³: exact
        return builder.fmul(mantissa, ir.Constant(ir.DoubleType(), 1.0 / 9007199254740992.0))

    return signature, codegen


# PCG64 (numpy's default bit generator): state ← a·state + inc (mod 2¹²⁸), output XSL-RR of the new state. k steps
# at once: state_k = A_k·state + G_k·inc with A_k = aᵏ and G_k = 1 + a + … + aᵏ⁻¹, so eight steps are eight
# independent multiplications instead of a chain of eight.
_PCG64_MULTIPLIER = (2549297995355413924 << 64) + 4865540595714422341
PCG64_LANES = 8    # `_pcg64_fill` spells out its eight lanes
PCG64_STEPS = 2 * PCG64_LANES     # A_k and G_k are tabled for k = 1 ... PCG64_STEPS (index k - 1)


def _pcg64_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    mask = (1 << 128) - 1
    powers, sums = [], []
    power, total = 1, 0
    for _ in range(PCG64_STEPS):
        total = (total * _PCG64_MULTIPLIER + 1) & mask
        power = (power * _PCG64_MULTIPLIER) & mask
        powers.append(power)
        sums.append(total)

    def halves(values):
        return (np.array([v >> 64 for v in values], dtype=np.uint64),
                np.array([v & ((1 << 64) - 1) for v in values], dtype=np.uint64))

    return (*halves(powers), *halves(sums))


_A_HIGH, _A_LOW, _G_HIGH, _G_LOW = _pcg64_tables()


@numba.njit(cache=True, inline="always")
def _lane(k, inc_high, inc_low):
    """G_k·inc (mod 2¹²⁸) as (high, low)."""
    zero = np.uint64(0)
    return _mul_add_128(_G_HIGH[k], _G_LOW[k], inc_high, inc_low, zero, zero)


@numba.njit(cache=True)
def _pcg64_fill(s_high, s_low, inc_high, inc_low, out, count):
    """out[:count] ← the uniforms of the PCG64 stream that follows state s (increment inc); returns the state
    after them."""
    # G_k·inc for the eight lanes, kept in a tuple (no array: this runs once per block of draws)
    c = (_lane(0, inc_high, inc_low), _lane(1, inc_high, inc_low), _lane(2, inc_high, inc_low),
         _lane(3, inc_high, inc_low), _lane(4, inc_high, inc_low), _lane(5, inc_high, inc_low),
         _lane(6, inc_high, inc_low), _lane(7, inc_high, inc_low))
    i = 0
    while i + PCG64_LANES <= count:
        high = s_high
        low = s_low
        for k in range(PCG64_LANES):
            high, low = _mul_add_128(_A_HIGH[k], _A_LOW[k], s_high, s_low, c[k][0], c[k][1])
            out[i + k] = _pcg64_double(high, low)
        s_high = high
        s_low = low
        i += PCG64_LANES
    while i < count:
        s_high, s_low = _mul_add_128(_A_HIGH[0], _A_LOW[0], s_high, s_low, inc_high, inc_low)
        out[i] = _pcg64_double(s_high, s_low)
        i += 1
    return s_high, s_low


@numba.njit(cache=True)
def _pcg64_jump(s_high, s_low, inc_high, inc_low, delta):
    """The PCG64 state `delta` steps after s (the LCG's jump-ahead by squaring, as PCG64.advance does)."""
    zero = np.uint64(0)
    one = np.uint64(1)
    multiplier_high, multiplier_low = _A_HIGH[0], _A_LOW[0]
    plus_high, plus_low = inc_high, inc_low
    total_m_high, total_m_low = zero, one          # the accumulated map x ↦ total_m·x + total_p
    total_p_high, total_p_low = zero, zero
    while delta > 0:
        if delta & 1:
            total_m_high, total_m_low = _mul_add_128(total_m_high, total_m_low, multiplier_high, multiplier_low, zero,
                                                     zero)
            total_p_high, total_p_low = _mul_add_128(total_p_high, total_p_low, multiplier_high, multiplier_low,
                                                     plus_high, plus_low)
        # (m, p) ↦ (m², (m + 1)·p): the map applied twice
        plus_high, plus_low = _mul_add_128(multiplier_high, multiplier_low, plus_high, plus_low, plus_high, plus_low)
        multiplier_high, multiplier_low = _mul_add_128(multiplier_high, multiplier_low, multiplier_high,
                                                       multiplier_low, zero, zero)
        delta >>= 1
    return _mul_add_128(total_m_high, total_m_low, s_high, s_low, total_p_high, total_p_low)


@numba.njit(cache=True)
def _pcg64_uniforms(state, out, count):
    """out[:count] ← the next `count` uniforms of the PCG64 whose pcg64_state is at address `state`."""
    pointer = np.intp(_load_u64(state))          # pcg64_state.pcg_state: {state, inc}, 128-bit little-endian
    s_high, s_low = _pcg64_fill(_load_u64(pointer + 8), _load_u64(pointer), _load_u64(pointer + 24),
                                _load_u64(pointer + 16), out, count)
    _store_u64(pointer, s_low)
    _store_u64(pointer + 8, s_high)


CHUNK = 8192       # draws per chunk of `parallel_uniforms`, about (the numbers do not depend on the chunks)


@numba.njit(cache=True)
def balanced_chunk(count, target):
    """The chunk size for spreading `count` items over threads in chunks of about `target`: one chunk when
    count <= target, else a number of chunks that is a multiple of 8 (for count up to target², 16.7 million
    with the filter's 4 096; beyond, the chunks are so many that one more or less is nothing), all of one
    size but the last.

    numba's prange gives each thread an equal share of the iterations, so with 25 chunks (N = 10⁵ in chunks
    of 4 096) one of two threads works 13 and the other 12: the step waits for the busier one. A multiple of
    8 chunks splits evenly over 1, 2, 4 or 8 threads. The size depends on `count` alone, so results that
    depend on the chunks do not depend on the threads.
    """
    chunks = (count + target - 1) // target
    if chunks <= 1:
        return target
    chunks = (chunks + 7) // 8 * 8
    return (count + chunks - 1) // chunks


@numba.njit(cache=True, parallel=True)
def parallel_uniforms(function, state, out, count):
    """`draw_uniforms` with the chunks of the stream drawn by several threads (numpy's PCG64: each chunk jumps
    ahead to where its numbers start); the same numbers, and the generator left at the same place."""
    if function != PCG64_INLINE:
        draw_uniforms(function, state, out, count)
        return
    pointer = np.intp(_load_u64(state))
    s_high = _load_u64(pointer + 8)
    s_low = _load_u64(pointer)
    inc_high = _load_u64(pointer + 24)
    inc_low = _load_u64(pointer + 16)
    chunk = balanced_chunk(count, CHUNK)
    chunks = (count + chunk - 1) // chunk
    for t in numba.prange(chunks):
        start = t * chunk
        stop = min(start + chunk, count)
        high, low = _pcg64_jump(s_high, s_low, inc_high, inc_low, start)
        _pcg64_fill(high, low, inc_high, inc_low, out[start:stop], stop - start)
    high, low = _pcg64_jump(s_high, s_low, inc_high, inc_low, count)
    _store_u64(pointer, low)
    _store_u64(pointer + 8, high)


@numba.njit(cache=True)
def _pcg64_next(state):
    pointer = np.intp(_load_u64(state))
    high, low = _mul_add_128(_A_HIGH[0], _A_LOW[0], _load_u64(pointer + 8), _load_u64(pointer),
                             _load_u64(pointer + 24), _load_u64(pointer + 16))
    _store_u64(pointer, low)
    _store_u64(pointer + 8, high)
    return _pcg64_double(high, low)


@numba.njit(cache=True)
def next_double(function, state):
    """One uniform on [0, 1) from a handle (`bit_generator_handle`): what `rng.random()` returns."""
    if function == PCG64_INLINE:
        return _pcg64_next(state)
    return _call_next_double(function, state)


@numba.njit(cache=True)
def draw_uniforms(function, state, out, count):
    """out[:count] ← the generator's next `count` uniforms (what `rng.random(count)` would return)."""
    if function == PCG64_INLINE:
        _pcg64_uniforms(state, out, count)
    else:
        for i in range(count):
            out[i] = _call_next_double(function, state)


@numba.njit(cache=True, inline="always")
def _column_uniform(s_high, s_low, j, increments):
    """The uniform in column j of a row whose state before it is s: PCG64 j + 1 steps on, A_{j+1}·s + G_{j+1}·inc."""
    high, low = _mul_add_128(_A_HIGH[j], _A_LOW[j], s_high, s_low, increments[j, 0], increments[j, 1])
    return _pcg64_double(high, low)


@numba.njit(cache=True, inline="always")
def _deferring_row(s_high, s_low, out, p, defer_from, defer_to, bases, increments):
    """Row p of `draw_rows_deferring` from the state before it, but its last column."""
    bases[p, 0] = s_high
    bases[p, 1] = s_low
    for j in range(defer_from):
        out[p, j] = _column_uniform(s_high, s_low, j, increments)
    for j in range(defer_to, out.shape[1] - 1):
        out[p, j] = _column_uniform(s_high, s_low, j, increments)


@numba.njit(cache=True)
def draw_rows_deferring(function, state, out, count, defer_from, defer_to, bases, increments):
    """out[:count] ← the generator's next uniforms as `rng.random((count, width))` lays them out, except that
    with numpy's PCG64 the columns defer_from..defer_to-1 (a kernel needs them for a few rows only) are not
    computed: bases[p] (high, low) keeps the state before row p and increments the G_k·inc, from which
    `deferred_uniform(bases, increments, p, j)` computes out[p, j] when it is needed. The generator is left
    where drawing every column leaves it. Returns True when columns were deferred; other generators draw every
    column and return False, as PCG64 does unless width <= PCG64_LANES and defer_from < defer_to < width.
    bases (>= count, 2) and increments (PCG64_STEPS, 2) are uint64 scratch.

    A row costs one 128-bit multiply-add per computed column (width 7 with three deferred: four instead of
    seven). Rows go in pairs, both states taken from the state before the pair, so that the chain from one
    row's state to the next is one multiply-add per two rows."""
    width = out.shape[1]
    if function != PCG64_INLINE or width > PCG64_LANES or defer_to >= width or defer_from >= defer_to:
        draw_uniforms(function, state, out.reshape(-1), width * count)
        return False
    pointer = np.intp(_load_u64(state))
    s_high = _load_u64(pointer + 8)
    s_low = _load_u64(pointer)
    inc_high = _load_u64(pointer + 24)
    inc_low = _load_u64(pointer + 16)
    for k in range(2 * width):
        increments[k, 0], increments[k, 1] = _lane(k, inc_high, inc_low)
    last = width - 1
    pair = 2 * width - 1
    p = 0
    while p + 1 < count:
        t_high, t_low = _mul_add_128(_A_HIGH[last], _A_LOW[last], s_high, s_low, increments[last, 0],
                                     increments[last, 1])
        u_high, u_low = _mul_add_128(_A_HIGH[pair], _A_LOW[pair], s_high, s_low, increments[pair, 0],
                                     increments[pair, 1])
        _deferring_row(s_high, s_low, out, p, defer_from, defer_to, bases, increments)
        out[p, last] = _pcg64_double(t_high, t_low)
        _deferring_row(t_high, t_low, out, p + 1, defer_from, defer_to, bases, increments)
        out[p + 1, last] = _pcg64_double(u_high, u_low)
        s_high = u_high
        s_low = u_low
        p += 2
    if p < count:
        _deferring_row(s_high, s_low, out, p, defer_from, defer_to, bases, increments)
        s_high, s_low = _mul_add_128(_A_HIGH[last], _A_LOW[last], s_high, s_low, increments[last, 0],
                                     increments[last, 1])
        out[p, last] = _pcg64_double(s_high, s_low)
    _store_u64(pointer, s_low)
    _store_u64(pointer + 8, s_high)
    return True


@numba.njit(cache=True, inline="always")
def deferred_uniform(bases, increments, p, j):
    """out[p, j] of a `draw_rows_deferring` call that deferred column j."""
    return _column_uniform(bases[p, 0], bases[p, 1], j, increments)


@numba.njit(cache=True)
def skip_doubles(count, function, state):
    """Draw and discard `count` uniforms: the generator ends where drawing them would leave it."""
    for _ in range(count):
        next_double(function, state)


# -- bounded integers as numpy draws them ------------------------------------------------------------------------
INTEGERS_LIMIT = 1 << 31     # `integers_function` handles rng.integers(0, high) for 1 <= high <= this


def integers_function(rng: np.random.Generator) -> int:
    """The address of `rng`'s bit generator's next_uint32, for `bounded_integers` (valid while it lives).

    next_uint32 is the generator's own function: with numpy's PCG64 it hands out the two halves of one 64-bit
    output in turn, and keeps the unused half in the bit generator's state, as `rng.integers` finds it."""
    return ctypes.cast(rng.bit_generator.ctypes.next_uint32, ctypes.c_void_p).value


_LAST_HANDLES: list[tuple] = []      # (bit generator, function, state, integers) of the last `draw_handles`


def draw_handles(rng: np.random.Generator) -> tuple[int, int, int]:
    """(function, state, integers): `bit_generator_handle(rng)` and `integers_function(rng)`, kept for the last
    generator asked about (looking them up costs a few µs; a caller that draws a few numbers per step from
    the same generator asks every step). The entry holds the bit generator, so the addresses stay valid."""
    bit_generator = rng.bit_generator
    last = _LAST_HANDLES[0] if _LAST_HANDLES else None
    if last is None or last[0] is not bit_generator:
        last = (bit_generator, *bit_generator_handle(rng), integers_function(rng))
        _LAST_HANDLES[:] = [last]
    return last[1], last[2], last[3]


@intrinsic
def _call_next_uint32(typingctx, function, state):
    """One next_uint32 draw (zero-extended to 64 bits) from a bit generator's function and state addresses."""
    signature = types.uint64(types.intp, types.intp)

    def codegen(context, builder, sig, args):
        void_pointer = ir.IntType(8).as_pointer()
        function_type = ir.FunctionType(ir.IntType(32), [void_pointer])
        callee = builder.inttoptr(args[0], function_type.as_pointer())
        return builder.zext(builder.call(callee, [builder.inttoptr(args[1], void_pointer)]), ir.IntType(64))

    return signature, codegen


@numba.njit(cache=True)
def bounded_integers(function, state, high, out):
    """out[:] ← what `rng.integers(0, high, size=len(out))` returns, leaving the generator where it would:
    Lemire's multiply-and-reject on next_uint32, as numpy draws int64 below 2³² (1 <= high <= INTEGERS_LIMIT;
    function from `integers_function`, state from `bit_generator_handle`). high = 1 draws nothing."""
    if high == 1:
        out[:] = 0
        return
    span = np.uint64(high)                   # numpy's rng_excl: the count of values
    low_mask = np.uint64(0xFFFFFFFF)
    threshold = (low_mask - (span - np.uint64(1))) % span
    for i in range(out.shape[0]):
        m = _call_next_uint32(function, state) * span
        if (m & low_mask) < span:            # rarely: reject the few products that would bias the result
            while (m & low_mask) < threshold:
                m = _call_next_uint32(function, state) * span
        out[i] = np.int64(m >> np.uint64(32))


_PCG64_LAYOUT: list[bool] = []


def _pcg64_layout_ok() -> bool:
    """Whether this numpy's PCG64 keeps its state as the kernels read it (checked once, on a scratch generator:
    the state words against `state`, then draws against `random()`)."""
    if not _PCG64_LAYOUT:
        ok = False
        try:
            probe, twin = np.random.PCG64(20240607), np.random.PCG64(20240607)
            address = probe.ctypes.state_address
            pointer = ctypes.cast(address, ctypes.POINTER(ctypes.c_void_p))[0]
            words = ctypes.cast(pointer, ctypes.POINTER(ctypes.c_uint64))
            state = probe.state["state"]
            ok = (words[0] | words[1] << 64) == state["state"] and (words[2] | words[3] << 64) == state["inc"]
            if ok:
                drawn = np.empty(21)
                _pcg64_uniforms(address, drawn, 20)
                drawn[20] = _pcg64_next(address)
                ok = np.array_equal(drawn, np.random.Generator(twin).random(21)) and probe.state == twin.state
        except Exception:        # any surprise: draw through next_double instead
            ok = False
        _PCG64_LAYOUT.append(bool(ok))
    return _PCG64_LAYOUT[0]


DRAWS = 256       # particles per block of uniforms drawn at once
MOVE_WORK = 6 * DRAWS     # the scratch of `move_range` and `move_range_fast`
NO_WORK = np.empty(0)     # (from Python; a kernel passes np.empty(0): a global array is read-only there)


@numba.njit(cache=True, inline="always")
def _move_work(work):
    """`work` if it holds MOVE_WORK floats, else a new scratch."""
    return work if work.shape[0] >= MOVE_WORK else np.empty(MOVE_WORK)


# -- sin and cos without libm ----------------------------------------------------------------------------------------
# A particle's heading needs its cos and sin at every motion update and every scoring. libm's are one call each,
# which no loop can vectorize, and their last bits depend on the C library's version. `sincos` is the fdlibm
# polynomial kernel after a Cody-Waite reduction by π/2, written branch-free so that a loop over particles
# vectorizes: for |x| <= 100 it is within 2.3·10⁻¹⁶ of the exact values (within one unit in the last place of
# libm's, which it equals in about three cases of four). It is inlined, so it is compiled with its caller's flags:
# plain IEEE arithmetic in the default kernels, where it gives the same bits on every machine as its numpy twin
# `sincos_reference`, and fast-math in the `fast=True` kernels.
_PIO2_HIGH = 1.57079632673412561417e+00     # the first 33 bits of π/2
_PIO2_LOW = 6.07710050650619224932e-11      # π/2 - _PIO2_HIGH
_TWO_OVER_PI = 6.36619772367581382433e-01
_S1, _S2, _S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
_S4, _S5, _S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
_C1, _C2, _C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
_C4, _C5, _C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11


@numba.njit(cache=True, inline="always")
def sincos(x):
    """(cos x, sin x) within 2.3·10⁻¹⁶ for |x| <= 100, branch-free (vectorizes); `sincos_reference` bit for bit
    in kernels compiled without fast-math."""
    k = np.floor(x * _TWO_OVER_PI + 0.5)              # the nearest multiple of π/2 (either one at a tie)
    r = (x - k * _PIO2_HIGH) - k * _PIO2_LOW
    z = r * r
    s = r + r * z * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
    c = 1.0 - 0.5 * z + z * z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6)))))
    quadrant = k - 4.0 * np.floor(k * 0.25)         # k mod 4, kept in floats (AVX2 has no double → int64)
    odd = (quadrant == 1.0) | (quadrant == 3.0)
    sine = c if odd else s
    cosine = s if odd else c
    sine = -sine if quadrant >= 2.0 else sine
    cosine = -cosine if (quadrant == 1.0) | (quadrant == 2.0) else cosine
    return cosine, sine


def sincos_reference(x) -> tuple[np.ndarray, np.ndarray]:
    """Numpy twin of `sincos`: the same operations, elementwise, so the same bits."""
    x = np.asarray(x, dtype=np.float64)
    k = np.floor(x * _TWO_OVER_PI + 0.5)
    r = (x - k * _PIO2_HIGH) - k * _PIO2_LOW
    z = r * r
    s = r + r * z * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
    c = 1.0 - 0.5 * z + z * z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6)))))
    quadrant = k - 4.0 * np.floor(k * 0.25)
    odd = (quadrant == 1.0) | (quadrant == 3.0)
    sine = np.where(odd, c, s)
    cosine = np.where(odd, s, c)
    return (np.where((quadrant == 1.0) | (quadrant == 2.0), -cosine, cosine),
            np.where(quadrant >= 2.0, -sine, sine))



# -- atan2 without libm ----------------------------------------------------------------------------------------------
# The exact bearing term needs the direction of each candidate landmark as an angle: one atan2 per particle and
# candidate. libm's is a call (about 24 ns in a loop over 2·10⁶ points) that no loop can vectorize. `atan2_poly`
# is fdlibm's atan kernel (its polynomial on three ranges of [0, 1], each with its own offset) on the smaller of
# |y|/|x| and |x|/|y|, then the quadrant, all written with selects, so that a loop over particles vectorizes
# (about 4 ns a point). Within two units in the last place of libm's atan2, equal to it in about three cases of
# four; the signs of zeros as atan2's. Inlined: compiled with its caller's flags; in plain IEEE arithmetic it
# gives the bits of its numpy twin `atan2_poly_reference` on every machine.
_AT0, _AT1, _AT2 = 3.33333333333329318027e-01, -1.99999999998764832476e-01, 1.42857142725034663711e-01
_AT3, _AT4, _AT5 = -1.11111104054623557880e-01, 9.09088713343650656196e-02, -7.69187620504482999495e-02
_AT6, _AT7, _AT8 = 6.66107313738753120669e-02, -5.83357013379057348645e-02, 4.97687799461593236017e-02
_AT9, _AT10 = -3.65315727442169155270e-02, 1.62858201153657823623e-02
_ATAN_HALF_HIGH, _ATAN_HALF_LOW = 4.63647609000806093515e-01, 2.26987774529616870924e-17    # atan(1/2)
_ATAN_ONE_HIGH, _ATAN_ONE_LOW = 7.85398163397448278999e-01, 3.06161699786838301793e-17      # atan(1)
_HALF_PI_HIGH, _HALF_PI_LOW = 1.57079632679489655800e+00, 6.12323399573676603587e-17
_PI_HIGH, _PI_LOW = 3.14159265358979311600e+00, 1.22464679914735317720e-16


@numba.njit(cache=True, inline="always")
def atan2_poly(y, x):
    """atan2(y, x) in [-π, π] for finite x and y, branch-free (vectorizes); `atan2_poly_reference` bit for bit in
    kernels compiled without fast-math. Zeros give ±0 or ±π as atan2 does; NaN in, NaN out."""
    ax = abs(x)
    ay = abs(y)
    steep = ay > ax
    numerator = ax if steep else ay
    denominator = ay if steep else ax
    a = numerator / denominator                               # in [0, 1]
    a = a if numerator > 0.0 else numerator + 0.0 * denominator     # 0/0 is 0 here; NaN stays NaN
    upper = a >= 0.6875
    middle = (a >= 0.4375) & (a < 0.6875)
    t = (a - 1.0 if upper else (2.0 * a - 1.0 if middle else a)) / (
        a + 1.0 if upper else (2.0 + a if middle else 1.0))
    high = _ATAN_ONE_HIGH if upper else (_ATAN_HALF_HIGH if middle else 0.0)
    low = _ATAN_ONE_LOW if upper else (_ATAN_HALF_LOW if middle else 0.0)
    z = t * t
    w = z * z
    s1 = z * (_AT0 + w * (_AT2 + w * (_AT4 + w * (_AT6 + w * (_AT8 + w * _AT10)))))
    s2 = w * (_AT1 + w * (_AT3 + w * (_AT5 + w * (_AT7 + w * _AT9))))
    r = high - ((t * (s1 + s2) - low) - t)                     # atan(a), in [0, π/4]
    r = (_HALF_PI_HIGH - r) + _HALF_PI_LOW if steep else r
    r = (_PI_HIGH - r) + _PI_LOW if math.copysign(1.0, x) < 0.0 else r
    return math.copysign(r, y)


def atan2_poly_reference(y, x) -> np.ndarray:
    """Numpy twin of `atan2_poly`: the same operations, elementwise, so the same bits."""
    y = np.asarray(y, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    ax = np.abs(x)
    ay = np.abs(y)
    steep = ay > ax
    numerator = np.where(steep, ax, ay)
    denominator = np.where(steep, ay, ax)
    with np.errstate(invalid="ignore", divide="ignore"):
        a = numerator / denominator
    a = np.where(numerator > 0.0, a, numerator + 0.0 * denominator)
    upper = a >= 0.6875
    middle = (a >= 0.4375) & (a < 0.6875)
    t = (np.where(upper, a - 1.0, np.where(middle, 2.0 * a - 1.0, a))
         / np.where(upper, a + 1.0, np.where(middle, 2.0 + a, 1.0)))
    high = np.where(upper, _ATAN_ONE_HIGH, np.where(middle, _ATAN_HALF_HIGH, 0.0))
    low = np.where(upper, _ATAN_ONE_LOW, np.where(middle, _ATAN_HALF_LOW, 0.0))
    z = t * t
    w = z * z
    s1 = z * (_AT0 + w * (_AT2 + w * (_AT4 + w * (_AT6 + w * (_AT8 + w * _AT10)))))
    s2 = w * (_AT1 + w * (_AT3 + w * (_AT5 + w * (_AT7 + w * _AT9))))
    r = high - ((t * (s1 + s2) - low) - t)
    r = np.where(steep, (_HALF_PI_HIGH - r) + _HALF_PI_LOW, r)
    r = np.where(np.copysign(1.0, x) < 0.0, (_PI_HIGH - r) + _PI_LOW, r)
    return np.copysign(r, y)

@numba.njit(cache=True, error_model="numpy")
def _move_rows(rows, count, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, noise):
    """Rows x, y, θ of a block moved by the robot-frame displacement (dx, dy, dθ) plus the robot-frame noise from
    noise[3p:3p + 3] (a loop over the particles of separate rows vectorizes, with `sincos`; over (N, 3) rows it
    does not)."""
    if gaussian:
        sx = bound_x / SQRT3
        sy = bound_y / SQRT3
        st = bound_theta / SQRT3
        for p in range(count):
            _move_row(rows, p, dx, dy, dtheta, noise[3 * p] * sx, noise[3 * p + 1] * sy, noise[3 * p + 2] * st)
    else:
        for p in range(count):
            _move_row(rows, p, dx, dy, dtheta, (2.0 * noise[3 * p] - 1.0) * bound_x,
                      (2.0 * noise[3 * p + 1] - 1.0) * bound_y, (2.0 * noise[3 * p + 2] - 1.0) * bound_theta)


@numba.njit(cache=True, inline="always")
def _move_row(rows, p, dx, dy, dtheta, ex, ey, et):
    theta = rows[2, p]
    c, s = sincos(theta)
    mx = dx + ex
    my = dy + ey
    rows[0, p] += c * mx - s * my
    rows[1, p] += s * mx + c * my
    rows[2, p] = wrap(theta + dtheta + et)


@numba.njit(cache=True, inline="always")
def _move_blocks(source, out, start, stop, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates,
                 function, state, work, fast):
    """`move_range` (`move_range_fast` when `fast`, a literal): a block of DRAWS particles at a time, copied into
    rows, moved there and copied out."""
    work = _move_work(work)
    uniforms = work[:3 * DRAWS]
    rows = work[3 * DRAWS:MOVE_WORK].reshape((3, DRAWS))
    for block in range(start, stop, DRAWS):
        end = min(block + DRAWS, stop)
        count = end - block
        if variates.shape[0] == 0:
            draw_uniforms(function, state, uniforms, 3 * count)
            noise = uniforms
        else:
            noise = variates[block:end].reshape(-1)
        for p in range(count):
            rows[0, p] = source[block + p, 0]
            rows[1, p] = source[block + p, 1]
            rows[2, p] = source[block + p, 2]
        if fast:
            _move_fast_rows(rows, count, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, noise)
        else:
            _move_rows(rows, count, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, noise)
        for p in range(count):
            out[block + p, 0] = rows[0, p]
            out[block + p, 1] = rows[1, p]
            out[block + p, 2] = rows[2, p]


@numba.njit(cache=True)
def move_range(source, out, start, stop, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates,
               function, state, work):
    """out[i] = source[i] moved, for i in [start, stop) (out may be source).

    The noise of particle i comes from variates[i] when `variates` has rows, else from three uniforms drawn
    here (x, y, θ in that order, as `rng.random((n, 3))` lays them out; uniform noise only). work: scratch of
    MOVE_WORK floats kept by a caller that moves a block at a time (`NO_WORK`: allocated here).
    """
    _move_blocks(source, out, start, stop, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates,
                 function, state, work, False)


@numba.njit(cache=True)
def move_with_noise(poses, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates):
    """Apply the robot-frame displacement (dx, dy, dtheta) to every pose, then add robot-frame noise.

    The noise of axis k is uniform on [-bound_k, bound_k] (Hoffmann eq. 10) from uniform variates u as
    (2u - 1)·bound, or, with `gaussian`, normal with the same variance (sigma = bound / sqrt(3)), so that
    switching the distribution keeps the spread. `variates` (N, 3) come from `draw_variates`.
    """
    move_range(poses, poses, 0, poses.shape[0], dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates,
               0, 0, np.empty(0))


@numba.njit(cache=True)
def move_drawing_noise(poses, dx, dy, dtheta, bound_x, bound_y, bound_theta, function, state):
    """`move_with_noise` with uniform noise whose variates are drawn in the kernel from a bit generator
    (`bit_generator_handle`): the same poses as `move_with_noise(..., False, rng.random((N, 3)))`."""
    move_range(poses, poses, 0, poses.shape[0], dx, dy, dtheta, bound_x, bound_y, bound_theta, False,
               np.empty((0, 3)), function, state, np.empty(0))


@numba.njit(cache=True, parallel=True)
def move_chunked(poses, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates, chunk):
    """`move_with_noise` with chunks of `chunk` particles on several threads (elementwise: the same poses)."""
    n = poses.shape[0]
    for t in numba.prange(max(1, (n + chunk - 1) // chunk)):
        move_range(poses, poses, t * chunk, min(n, (t + 1) * chunk), dx, dy, dtheta, bound_x, bound_y,
                   bound_theta, gaussian, variates, 0, 0, np.empty(0))


# -- the opt-in fast variant ----------------------------------------------------------------------------------------
# `move_range_fast`: the same polynomial sin and cos and a branch-free wrap, compiled with fast-math (contracted
# into fused multiply-adds, reassociated): the same draws, the poses to rounding. The filter uses it only with
# `fast=True`.
FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}    # fast-math without assuming no NaN / inf


@numba.njit(cache=True, fastmath=FAST, inline="always")
def fast_wrap(a):
    """`field.angles.wrap_angle` to rounding, branch-free."""
    r = a - TWO_PI * np.floor((a + math.pi) * (1.0 / TWO_PI))
    r = r + TWO_PI if r <= -math.pi else r
    return r - TWO_PI if r > math.pi else r


@numba.njit(cache=True, fastmath=FAST, error_model="numpy")
def _move_fast_rows(rows, count, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, noise):
    """Rows x, y, θ of a block moved (a loop over the particles of separate rows vectorizes; over (N, 3) rows
    it does not)."""
    if gaussian:
        scale_x = bound_x / SQRT3
        scale_y = bound_y / SQRT3
        scale_theta = bound_theta / SQRT3
        shift_x = shift_y = shift_theta = 0.0
    else:
        scale_x = 2.0 * bound_x
        scale_y = 2.0 * bound_y
        scale_theta = 2.0 * bound_theta
        shift_x, shift_y, shift_theta = bound_x, bound_y, bound_theta
    for p in range(count):
        ex = noise[3 * p] * scale_x - shift_x
        ey = noise[3 * p + 1] * scale_y - shift_y
        et = noise[3 * p + 2] * scale_theta - shift_theta
        theta = rows[2, p]
        c, s = sincos(theta)
        mx = dx + ex
        my = dy + ey
        rows[0, p] += c * mx - s * my
        rows[1, p] += s * mx + c * my
        rows[2, p] = fast_wrap(theta + dtheta + et)


@numba.njit(cache=True)
def move_range_fast(source, out, start, stop, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates,
                    function, state, work):
    """`move_range` with fast-math: the same draws, the poses to rounding."""
    _move_blocks(source, out, start, stop, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates,
                 function, state, work, True)


def move_with_noise_reference(poses, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates):
    """Plain numpy twin of `move_with_noise` (the same variates give the same poses)."""
    if gaussian:
        noise = variates * (np.array([bound_x, bound_y, bound_theta]) / SQRT3)
    else:
        noise = (2.0 * variates - 1.0) * np.array([bound_x, bound_y, bound_theta])
    theta = poses[:, 2].copy()
    c, s = sincos_reference(theta)
    mx = dx + noise[:, 0]
    my = dy + noise[:, 1]
    poses[:, 0] += c * mx - s * my
    poses[:, 1] += s * mx + c * my
    poses[:, 2] = wrap_angles(theta + dtheta + noise[:, 2])
