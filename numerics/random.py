"""Random numbers in kernels: the filter's one numpy Generator, drawn from compiled code.

    from numerics.random import draw_variates, bit_generator_handle, next_double, draw_uniforms, parallel_uniforms

Kernels take pre-drawn variates (drawn from the filter's one Generator by `draw_variates`), so a kernel is a
deterministic function of its inputs and its numpy twin reproduces it from the same variates. (Passing the
Generator itself into numba costs about 10 µs of unboxing per call, more than the whole kernel at N = 100.)

A kernel may instead draw uniforms itself from the Generator's bit generator (`bit_generator_handle`,
`next_double`, `draw_uniforms`): the same numbers, in the same order, as `rng.random()` would give, without
an array that grows with N, a pass over it, or the Python call that fills it; numpy's PCG64 (the default)
is stepped in the kernel, eight independent steps at a time, and `parallel_uniforms` lets threads draw
their chunks of the same stream (jumping ahead). `bounded_integers` draws `rng.integers(0, high)` likewise.
"""

import ctypes
from typing import Any

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from .chunks import CHUNK, balanced_chunk


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
PCG64_INLINE = 0  # the `function` of a handle whose generator is numpy's PCG64, stepped in the kernel itself


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
    return _address(interface.next_double), interface.state_address


def _address(function: Any) -> int:
    """The address of a ctypes function pointer (a bit generator's are never null)."""
    address = ctypes.cast(function, ctypes.c_void_p).value
    if address is None:
        raise ValueError("the bit generator has a null function pointer")
    return address


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
        mantissa = builder.sitofp(builder.lshr(word, ir.Constant(i64, 11)), ir.DoubleType())  # < 2⁵³: exact
        return builder.fmul(mantissa, ir.Constant(ir.DoubleType(), 1.0 / 9007199254740992.0))

    return signature, codegen


# PCG64 (numpy's default bit generator): state ← a·state + inc (mod 2¹²⁸), output XSL-RR of the new state. k steps
# at once: state_k = A_k·state + G_k·inc with A_k = aᵏ and G_k = 1 + a + … + aᵏ⁻¹, so eight steps are eight
# independent multiplications instead of a chain of eight.
_PCG64_MULTIPLIER = (2549297995355413924 << 64) + 4865540595714422341
PCG64_LANES = 8  # `_pcg64_fill` spells out its eight lanes
PCG64_STEPS = 2 * PCG64_LANES  # A_k and G_k are tabled for k = 1 ... PCG64_STEPS (index k - 1)


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
        return (
            np.array([v >> 64 for v in values], dtype=np.uint64),
            np.array([v & ((1 << 64) - 1) for v in values], dtype=np.uint64),
        )

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
    c = (
        _lane(0, inc_high, inc_low),
        _lane(1, inc_high, inc_low),
        _lane(2, inc_high, inc_low),
        _lane(3, inc_high, inc_low),
        _lane(4, inc_high, inc_low),
        _lane(5, inc_high, inc_low),
        _lane(6, inc_high, inc_low),
        _lane(7, inc_high, inc_low),
    )
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
    total_m_high, total_m_low = zero, one  # the accumulated map x ↦ total_m·x + total_p
    total_p_high, total_p_low = zero, zero
    while delta > 0:
        if delta & 1:
            total_m_high, total_m_low = _mul_add_128(
                total_m_high, total_m_low, multiplier_high, multiplier_low, zero, zero
            )
            total_p_high, total_p_low = _mul_add_128(
                total_p_high, total_p_low, multiplier_high, multiplier_low, plus_high, plus_low
            )
        # (m, p) ↦ (m², (m + 1)·p): the map applied twice
        plus_high, plus_low = _mul_add_128(multiplier_high, multiplier_low, plus_high, plus_low, plus_high, plus_low)
        multiplier_high, multiplier_low = _mul_add_128(
            multiplier_high, multiplier_low, multiplier_high, multiplier_low, zero, zero
        )
        delta >>= 1
    return _mul_add_128(total_m_high, total_m_low, s_high, s_low, total_p_high, total_p_low)


@numba.njit(cache=True)
def _pcg64_uniforms(state, out, count):
    """out[:count] ← the next `count` uniforms of the PCG64 whose pcg64_state is at address `state`."""
    pointer = np.intp(_load_u64(state))  # pcg64_state.pcg_state: {state, inc}, 128-bit little-endian
    s_high, s_low = _pcg64_fill(
        _load_u64(pointer + 8), _load_u64(pointer), _load_u64(pointer + 24), _load_u64(pointer + 16), out, count
    )
    _store_u64(pointer, s_low)
    _store_u64(pointer + 8, s_high)


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
    high, low = _mul_add_128(
        _A_HIGH[0],
        _A_LOW[0],
        _load_u64(pointer + 8),
        _load_u64(pointer),
        _load_u64(pointer + 24),
        _load_u64(pointer + 16),
    )
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
        t_high, t_low = _mul_add_128(
            _A_HIGH[last], _A_LOW[last], s_high, s_low, increments[last, 0], increments[last, 1]
        )
        u_high, u_low = _mul_add_128(
            _A_HIGH[pair], _A_LOW[pair], s_high, s_low, increments[pair, 0], increments[pair, 1]
        )
        _deferring_row(s_high, s_low, out, p, defer_from, defer_to, bases, increments)
        out[p, last] = _pcg64_double(t_high, t_low)
        _deferring_row(t_high, t_low, out, p + 1, defer_from, defer_to, bases, increments)
        out[p + 1, last] = _pcg64_double(u_high, u_low)
        s_high = u_high
        s_low = u_low
        p += 2
    if p < count:
        _deferring_row(s_high, s_low, out, p, defer_from, defer_to, bases, increments)
        s_high, s_low = _mul_add_128(
            _A_HIGH[last], _A_LOW[last], s_high, s_low, increments[last, 0], increments[last, 1]
        )
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
INTEGERS_LIMIT = 1 << 31  # `integers_function` handles rng.integers(0, high) for 1 <= high <= this


def integers_function(rng: np.random.Generator) -> int:
    """The address of `rng`'s bit generator's next_uint32, for `bounded_integers` (valid while it lives).

    next_uint32 is the generator's own function: with numpy's PCG64 it hands out the two halves of one 64-bit
    output in turn, and keeps the unused half in the bit generator's state, as `rng.integers` finds it."""
    return _address(rng.bit_generator.ctypes.next_uint32)


_LAST_HANDLES: list[tuple] = []  # (bit generator, function, state, integers) of the last `draw_handles`


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
    span = np.uint64(high)  # numpy's rng_excl: the count of values
    low_mask = np.uint64(0xFFFFFFFF)
    threshold = (low_mask - (span - np.uint64(1))) % span
    for i in range(out.shape[0]):
        m = _call_next_uint32(function, state) * span
        if (m & low_mask) < span:  # rarely: reject the few products that would bias the result
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
        except Exception:  # any surprise: draw through next_double instead
            ok = False
        _PCG64_LAYOUT.append(bool(ok))
    return _PCG64_LAYOUT[0]
