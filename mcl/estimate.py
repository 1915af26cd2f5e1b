"""The belief's summary: the pose estimate of the dominant cluster, and grid entropy (Hoffmann eq. 27).

    from mcl.estimate import cluster_estimate, grid_entropy, credible_region_contains, belief_log_density

The field is point-symmetric, so a lost filter may hold two mirror modes; their mean is the centre of the
field, facing nowhere. The estimate is therefore the weighted circular mean of the dominant cluster: the
heaviest cell of a coarse (x, y, θ) histogram seeds a few rounds of mean shift with a flat kernel (heading
averaged as wrapped residuals about the current centre, the intrinsic circular mean), and the covariance is
that of the particles the kernel holds. The cluster's share of the weight is returned too.

Entropy is computed on a grid as in the paper, position and orientation separately, in bits:
H = -Σ p(sᵢ) log₂ p(sᵢ), p(sᵢ) the weight in cell i. It lies in [0, log₂(cells)] and is zero while every
particle shares one cell.

`credible_region_contains` tells whether a pose lies in the smallest region holding 95 % of the belief: the
check that the truth stays inside the particle cloud. `belief_log_density` is the log of the same kernel
density at a pose, normalised: at the true pose, a score that also rewards a tight cloud.

The filter fills the estimate's and the entropy's histograms in one pass and keeps them until the particles
change (`summary_fill`, `summary_estimate`, `summary_entropy`): the results of `cluster_estimate` and
`grid_entropy` bit for bit. `summary_estimate_chunked` (several threads) and `summary_estimate_fast`
(reassociated sums) are its opt-in variants, equal to rounding.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from field.angles import wrap_angles
from field.moved import moved_names
from numerics.compile import variant
from numerics.trig import wrap

# The numpy twins moved to the package's `reference` module; their old names still work, with a warning.
__getattr__ = moved_names(
    __name__,
    {
        "grid_entropy_reference": "mcl.reference.grid_entropy",
        "cluster_estimate_reference": "mcl.reference.cluster_estimate",
    },
)


@numba.njit(cache=True, inline="always")
def _cell(value, origin, size, count):
    """The cell of `value` among `count` cells of `size` from `origin`, clamped to the first and last cell; a
    NaN falls in the first (a broken model's poses must not index outside the histograms)."""
    q = math.floor((value - origin) / size)
    if not q >= 0.0:
        return 0
    if q >= count:
        return count - 1
    return int(q)


BLOCK = 256  # particles per block of the vectorized loops below


@numba.njit(cache=True, inline="always")
def _cell_float(value, origin, size, count):
    """`_cell` as a float (exact), for vectorized loops (a NaN falls in the first cell, as in `_cell`)."""
    c = np.floor((value - origin) / size)
    c = c if c >= 0.0 else 0.0
    return count - 1.0 if c >= count else c


# -- mean shift and covariance of the dominant cluster --------------------------------------------------------
# The sums run over the particles in index order, as they always have (the estimate is reproducible to the
# bit), but everything else is computed for a block of particles at a time by loops that vectorize: the
# offsets from the centre, the wrapped heading residual, the kernel's membership and the weighted terms
# (a particle outside the kernel adds a weight of zero: the sums are the same, since adding ±0 to a sum that
# starts at +0 changes nothing). The sums over a block are then a short chain of additions.

# (The block kernels take slices and index them from 0: an index offset by a variable start would need
# numba's negative-index wraparound, which keeps LLVM from vectorizing.)


@numba.njit(cache=True, error_model="numpy")
def _kernel_terms(xs, ys, ts, weights, count, cx, cy, ct, r2, angle_radius, rows):
    for p in range(count):
        dx = xs[p] - cx
        dy = ys[p] - cy
        dt = wrap(ts[p] - ct)
        inside = (dx * dx + dy * dy <= r2) & (abs(dt) <= angle_radius)
        w = weights[p] if inside else 0.0
        rows[0, p] = w * dx
        rows[1, p] = w * dy
        rows[2, p] = w * dt
        rows[3, p] = w


def _kernel_mean_body(xs, ys, ts, weights, cx, cy, ct, radius, angle_radius, scratch, chunk):
    """Weighted mean of the particles within the flat kernel around (cx, cy, ct).

    The heading is the intrinsic circular mean: the centre plus the weighted mean of the wrapped residuals
    (one step of the Fréchet-mean iteration on the circle; repeated calls converge). Within the kernel's
    ±angle_radius this needs no trigonometry. The sums are taken chunk by chunk (within a chunk in index order,
    then over the chunks in order): `_kernel_mean` compiles this with one chunk of every particle (ONE_CHUNK,
    scratch: (>= 4, BLOCK) rows, chunk unused), `_kernel_mean_chunked` with chunks of `chunk` on threads.
    """
    n = xs.shape[0]
    if ONE_CHUNK:
        chunk = max(n, 1)
    chunks = max(1, (n + chunk - 1) // chunk)
    # each chunk's sums (one chunk: the first row of the scratch, once its rows are done with)
    partial = scratch if ONE_CHUNK else np.zeros((chunks, 4))
    r2 = radius * radius
    for t in numba.prange(chunks):
        if ONE_CHUNK:
            rows = scratch
        else:
            rows = np.empty((4, BLOCK))
        sx = 0.0
        sy = 0.0
        st = 0.0
        total = 0.0
        for start in range(t * chunk, min(n, (t + 1) * chunk), BLOCK):
            stop = min(start + BLOCK, n, (t + 1) * chunk)
            count = stop - start
            _kernel_terms(
                xs[start:stop],
                ys[start:stop],
                ts[start:stop],
                weights[start:stop],
                count,
                cx,
                cy,
                ct,
                r2,
                angle_radius,
                rows,
            )
            for p in range(count):
                sx += rows[0, p]
                sy += rows[1, p]
                st += rows[2, p]
                total += rows[3, p]
        partial[t, 0] = sx
        partial[t, 1] = sy
        partial[t, 2] = st
        partial[t, 3] = total
    sx = 0.0
    sy = 0.0
    st = 0.0
    total = 0.0
    for t in range(chunks):
        sx += partial[t, 0]
        sy += partial[t, 1]
        st += partial[t, 2]
        total += partial[t, 3]
    if total <= 0.0:
        return cx, cy, ct, 0.0
    return cx + sx / total, cy + sy / total, wrap(ct + st / total), total


# Whether a variant of the bodies above and below takes its sums in one chunk (the serial kernels), bound by
# each variant (`numerics.compile.variant`).
ONE_CHUNK = True
_kernel_mean = variant(_kernel_mean_body, "serial", {"ONE_CHUNK": True})


@numba.njit(cache=True, error_model="numpy")
def _covariance_terms(xs, ys, ts, weights, count, mx, my, mt, r2, angle_radius, total, rows):
    for p in range(count):
        dx = xs[p] - mx
        dy = ys[p] - my
        dt = wrap(ts[p] - mt)
        inside = (dx * dx + dy * dy <= r2) & (abs(dt) <= angle_radius)
        w = weights[p] / total if inside else 0.0
        rows[0, p] = w * dx * dx
        rows[1, p] = w * dx * dy
        rows[2, p] = w * dx * dt
        rows[3, p] = w * dy * dy
        rows[4, p] = w * dy * dt
        rows[5, p] = w * dt * dt


def _kernel_covariance_body(xs, ys, ts, weights, mx, my, mt, radius, angle_radius, total, scratch, out_cov, chunk):
    """Covariance of the particles within the kernel around the mean (mx, my, mt), θ residual wrapped; its sums
    in chunks as `_kernel_mean_body` takes them (`_kernel_covariance`: one chunk, scratch (6, BLOCK) rows;
    `_kernel_covariance_chunked`: chunks of `chunk` on threads)."""
    n = xs.shape[0]
    if ONE_CHUNK:
        chunk = max(n, 1)
    chunks = max(1, (n + chunk - 1) // chunk)
    if not total > 0.0:
        out_cov[:, :] = 0.0
        return
    # each chunk's sums (one chunk: the first row of the scratch, once its rows are done with)
    partial = scratch if ONE_CHUNK else np.zeros((chunks, 6))
    r2 = radius * radius
    for t in numba.prange(chunks):
        if ONE_CHUNK:
            rows = scratch
        else:
            rows = np.empty((6, BLOCK))
        s0 = s1 = s2 = s3 = s4 = s5 = 0.0
        for start in range(t * chunk, min(n, (t + 1) * chunk), BLOCK):
            stop = min(start + BLOCK, n, (t + 1) * chunk)
            count = stop - start
            _covariance_terms(
                xs[start:stop],
                ys[start:stop],
                ts[start:stop],
                weights[start:stop],
                count,
                mx,
                my,
                mt,
                r2,
                angle_radius,
                total,
                rows,
            )
            for p in range(count):
                s0 += rows[0, p]
                s1 += rows[1, p]
                s2 += rows[2, p]
                s3 += rows[3, p]
                s4 += rows[4, p]
                s5 += rows[5, p]
        partial[t, 0] = s0
        partial[t, 1] = s1
        partial[t, 2] = s2
        partial[t, 3] = s3
        partial[t, 4] = s4
        partial[t, 5] = s5
    c0 = c1 = c2 = c3 = c4 = c5 = 0.0
    for t in range(chunks):
        c0 += partial[t, 0]
        c1 += partial[t, 1]
        c2 += partial[t, 2]
        c3 += partial[t, 3]
        c4 += partial[t, 4]
        c5 += partial[t, 5]
    out_cov[0, 0] = c0
    out_cov[0, 1] = out_cov[1, 0] = c1
    out_cov[0, 2] = out_cov[2, 0] = c2
    out_cov[1, 1] = c3
    out_cov[1, 2] = out_cov[2, 1] = c4
    out_cov[2, 2] = c5


_kernel_covariance = variant(_kernel_covariance_body, "serial", {"ONE_CHUNK": True})


@numba.njit(cache=True, inline="always")
def _cell_centre(best, x_min, y_min, cell_size, ny, n_theta):
    """The centre (x, y, θ) of cell `best` of the (x, y, θ) histogram."""
    bt = best % n_theta
    by = (best // n_theta) % ny
    bx = best // (n_theta * ny)
    return (
        x_min + (bx + 0.5) * cell_size,
        y_min + (by + 0.5) * cell_size,
        -math.pi + (bt + 0.5) * (2.0 * math.pi / n_theta),
    )


def _dominant_cluster_body(xs, ys, ts, weights, best, cells, shift, previous, use_previous, out_mean, out_cov, chunk=0):
    """Mean shift from the centre of histogram cell `best` (and from `previous`), then the covariance; returns
    the cluster's weight. xs, ys, ts: the particles' coordinates as separate arrays; cells, shift: the groups of
    `cluster_estimate`. (A template: `_dominant_cluster` and its fast and chunked variants, below, compile it
    with their `kernel_mean` and `kernel_covariance`; chunk: the chunked kernels' chunk size.)"""
    x_min, y_min, cell_size, _, ny, n_theta = cells
    radius, angle_radius, iterations = shift
    rows = np.empty((6, BLOCK))
    # Seed: the centre of the heaviest cell; the kernel is wider than a cell, so mean shift merges its
    # neighbours and walks to the mode.
    mx, my, mt = _cell_centre(best, x_min, y_min, cell_size, ny, n_theta)
    total = 0.0
    for _ in range(iterations):
        mx, my, mt, total = kernel_mean(xs, ys, ts, weights, mx, my, mt, radius, angle_radius, rows, chunk)
    if use_previous and total < 0.5:
        px, py, pt, ptotal = previous[0], previous[1], previous[2], 0.0
        for _ in range(iterations):
            px, py, pt, ptotal = kernel_mean(xs, ys, ts, weights, px, py, pt, radius, angle_radius, rows, chunk)
        if ptotal > total:
            mx, my, mt, total = px, py, pt, ptotal
    kernel_covariance(xs, ys, ts, weights, mx, my, mt, radius, angle_radius, total, rows, out_cov, chunk)
    out_mean[0] = mx
    out_mean[1] = my
    out_mean[2] = wrap(mt)
    return total


# The kernels the template above calls by these names, bound by each variant (`numerics.compile.variant`).
kernel_mean = kernel_covariance = dominant_cluster = None
_dominant_cluster = variant(
    _dominant_cluster_body, "serial", {"kernel_mean": _kernel_mean, "kernel_covariance": _kernel_covariance}
)


@numba.njit(cache=True)
def cluster_estimate(poses, weights, cells, shift, histogram, previous, use_previous, out_mean, out_cov):
    """Mean and covariance of the dominant cluster; returns the cluster's weight.

    Two groups of parameters: cells (x_min, y_min, cell_size, nx, ny, n_theta), the histogram's grid of
    cell_size-wide cells from (x_min, y_min) and n_theta orientation bins; shift (radius, angle_radius,
    iterations), the mean shift's kernel and its iterations. histogram: scratch of nx·ny·n_theta floats. out_mean (3,), out_cov (3, 3) are written. When the cluster
    grown from the heaviest cell holds less than half the weight and `use_previous`, the mean shift also
    starts from `previous` (the last estimate) and the heavier of the two clusters wins: a tight cluster
    split across cell boundaries then is not lost to a clump that fits in one cell.
    """
    x_min, y_min, cell_size, nx, ny, n_theta = cells
    histogram[:] = 0.0
    theta_size = 2.0 * math.pi / n_theta
    for i in range(poses.shape[0]):
        cx = _cell(poses[i, 0], x_min, cell_size, nx)
        cy = _cell(poses[i, 1], y_min, cell_size, ny)
        ct = _cell(poses[i, 2], -math.pi, theta_size, n_theta)
        histogram[(cx * ny + cy) * n_theta + ct] += weights[i]
    return _dominant_cluster(
        np.ascontiguousarray(poses[:, 0]),
        np.ascontiguousarray(poses[:, 1]),
        np.ascontiguousarray(poses[:, 2]),
        weights,
        np.argmax(histogram),
        cells,
        shift,
        previous,
        use_previous,
        out_mean,
        out_cov,
    )


@numba.njit(cache=True)
def _entropy_bits(histogram):
    h = 0.0
    for p in histogram:
        if p > 0.0:
            h -= p * math.log2(p)
    return max(h, 0.0)


@numba.njit(cache=True)
def grid_entropy(poses, weights, x_min, y_min, cell_size, nx, ny, n_theta, position_histogram, orientation_histogram):
    """Position and orientation entropy in bits (Hoffmann eq. 27) on a grid; weights must sum to one.

    Particles beyond the grid count in its border cells. The histograms are scratch arrays of nx·ny and
    n_theta floats.
    """
    position_histogram[:] = 0.0
    orientation_histogram[:] = 0.0
    theta_size = 2.0 * math.pi / n_theta
    for i in range(poses.shape[0]):
        cx = _cell(poses[i, 0], x_min, cell_size, nx)
        cy = _cell(poses[i, 1], y_min, cell_size, ny)
        position_histogram[cx * ny + cy] += weights[i]
        orientation_histogram[_cell(poses[i, 2], -math.pi, theta_size, n_theta)] += weights[i]
    return _entropy_bits(position_histogram), _entropy_bits(orientation_histogram)


# -- the filter's summary: the histograms of the estimate and of the entropy in one pass --------------------------
# A filter that asks for both the estimate and the entropy after each step would bin every particle twice,
# and at N = 100 clearing and scanning the 7 696 cells of the position grid costs more than the particles.
# The summary keeps the three histograms with a bitmap of the cells that hold weight: filling them is one
# pass over the particles (which also lays out their coordinates as separate arrays for the mean shift);
# the dominant cell, the entropies and the clearing visit the marked cells only, in index order, so every
# sum and every tie is resolved as the full scans above resolve them.


@intrinsic
def _trailing_zeros(typingctx, word):
    """Index of the lowest set bit of a nonzero uint64 (llvm.cttz)."""
    signature = types.uint64(types.uint64)

    def codegen(context, builder, sig, args):
        int64 = ir.IntType(64)
        function = builder.module.declare_intrinsic(
            "llvm.cttz", [int64], ir.FunctionType(int64, [int64, ir.IntType(1)])
        )
        return builder.call(function, [args[0], ir.Constant(ir.IntType(1), 1)])

    return signature, codegen


@numba.njit(cache=True)
def _clear_marked(histogram, bitmap):
    for word_index in range(bitmap.shape[0]):
        word = bitmap[word_index]
        while word != 0:
            histogram[word_index * 64 + np.int64(_trailing_zeros(word))] = 0.0
            word &= word - np.uint64(1)
        bitmap[word_index] = 0


@numba.njit(cache=True)
def _marked_argmax(histogram, bitmap):
    """np.argmax(histogram) when every unmarked cell is zero and some marked cell is positive."""
    best = 0
    best_value = -np.inf
    for word_index in range(bitmap.shape[0]):
        word = bitmap[word_index]
        while word != 0:
            cell = word_index * 64 + np.int64(_trailing_zeros(word))
            if histogram[cell] > best_value:
                best_value = histogram[cell]
                best = cell
            word &= word - np.uint64(1)
    return best


@numba.njit(cache=True)
def _marked_entropy_bits(histogram, bitmap):
    """_entropy_bits(histogram) when every unmarked cell is zero."""
    h = 0.0
    for word_index in range(bitmap.shape[0]):
        word = bitmap[word_index]
        while word != 0:
            p = histogram[word_index * 64 + np.int64(_trailing_zeros(word))]
            if p > 0.0:
                h -= p * math.log2(p)
            word &= word - np.uint64(1)
    return max(h, 0.0)


# Summary grid parameters, one float64 array (counts as floats).
(
    G_X_MIN,
    G_Y_MIN,
    G_CLUSTER_CELL,
    G_CLUSTER_NX,
    G_CLUSTER_NY,
    G_CLUSTER_NT,
    G_RADIUS,
    G_ANGLE_RADIUS,
    G_ITERATIONS,
    G_POSITION_CELL,
    G_ENTROPY_NX,
    G_ENTROPY_NY,
    G_ENTROPY_NT,
) = range(13)


def summary_grid(
    x_min,
    y_min,
    cluster_cell,
    cluster_nx,
    cluster_ny,
    cluster_orientation_bins,
    cluster_radius,
    cluster_angle_radius,
    iterations,
    position_cell,
    entropy_nx,
    entropy_ny,
    orientation_bins,
):
    """The parameter array of the summary kernels (see `mcl.filter.Grid`)."""
    return np.array(
        [
            x_min,
            y_min,
            cluster_cell,
            cluster_nx,
            cluster_ny,
            cluster_orientation_bins,
            cluster_radius,
            cluster_angle_radius,
            iterations,
            position_cell,
            entropy_nx,
            entropy_ny,
            orientation_bins,
        ],
        dtype=np.float64,
    )


@numba.njit(cache=True)
def _layout(grid):
    """Sizes of the cluster, position and orientation histograms, laid end to end in one array (their bitmaps
    likewise, 64 cells a word)."""
    cluster = int(grid[G_CLUSTER_NX]) * int(grid[G_CLUSTER_NY]) * int(grid[G_CLUSTER_NT])
    position = int(grid[G_ENTROPY_NX]) * int(grid[G_ENTROPY_NY])
    return cluster, position, int(grid[G_ENTROPY_NT])


def summary_buffers(grid, n):
    """The summary's arrays: coordinates (3, n) (x, y, θ rows for the mean shift), the three histograms end to
    end and their bitmaps (both zero)."""
    sizes = _layout(grid)
    return (np.empty((3, n)), np.zeros(sum(sizes)), np.zeros(sum((size + 63) // 64 for size in sizes), dtype=np.uint64))


@numba.njit(cache=True)
def _parts(grid, histograms, bitmaps):
    """The cluster, position and orientation histograms and bitmaps, as views."""
    cluster, position, orientation = _layout(grid)
    wc = (cluster + 63) // 64
    wp = (position + 63) // 64
    return (
        histograms[:cluster],
        histograms[cluster : cluster + position],
        histograms[cluster + position :],
        bitmaps[:wc],
        bitmaps[wc : wc + wp],
        bitmaps[wc + wp :],
    )


@numba.njit(cache=True, error_model="numpy")
def _summary_cells(grid, xs, ys, ts, count, cells):
    """The cluster, position and orientation cells (rows of `cells`) of a block of particles."""
    x_min = grid[G_X_MIN]
    y_min = grid[G_Y_MIN]
    cluster_cell = grid[G_CLUSTER_CELL]
    cluster_nx = grid[G_CLUSTER_NX]
    cluster_ny = grid[G_CLUSTER_NY]
    cluster_nt = grid[G_CLUSTER_NT]
    cluster_theta = 2.0 * math.pi / int(cluster_nt)
    position_cell = grid[G_POSITION_CELL]
    entropy_nx = grid[G_ENTROPY_NX]
    entropy_ny = grid[G_ENTROPY_NY]
    entropy_nt = grid[G_ENTROPY_NT]
    entropy_theta = 2.0 * math.pi / int(entropy_nt)
    for p in range(count):
        x = xs[p]
        y = ys[p]
        theta = ts[p]
        cell = (
            _cell_float(x, x_min, cluster_cell, cluster_nx) * cluster_ny
            + _cell_float(y, y_min, cluster_cell, cluster_ny)
        ) * cluster_nt + _cell_float(theta, -math.pi, cluster_theta, cluster_nt)
        cells[0, p] = np.int32(cell)
        cell = _cell_float(x, x_min, position_cell, entropy_nx) * entropy_ny + _cell_float(
            y, y_min, position_cell, entropy_ny
        )
        cells[1, p] = np.int32(cell)
        cells[2, p] = np.int32(_cell_float(theta, -math.pi, entropy_theta, entropy_nt))


@numba.njit(cache=True)
def _deinterleave(poses, count, xs, ys, ts):
    for p in range(count):
        xs[p] = poses[p, 0]
        ys[p] = poses[p, 1]
        ts[p] = poses[p, 2]


@numba.njit(cache=True)
def summary_fill(grid, poses, weights, coordinates, histograms, bitmaps):
    """Clear the histograms, then bin every particle into the cluster, position and orientation histograms
    (as `cluster_estimate` and `grid_entropy` bin them), marking each cell as it first receives weight. The
    coordinates are copied to the rows of `coordinates` (x, y, θ) on the way; with `poses` of no rows they
    are taken from there (written by `mcl.resampling.resample_with_jitter`)."""
    cluster, position, orientation, cluster_bits, position_bits, orientation_bits = _parts(grid, histograms, bitmaps)
    _clear_marked(cluster, cluster_bits)
    _clear_marked(position, position_bits)
    _clear_marked(orientation, orientation_bits)
    cells = np.empty((3, BLOCK), dtype=np.int32)
    one = np.uint64(1)
    n = weights.shape[0]
    copy = poses.shape[0] > 0
    # The cluster and orientation cells are coarse: a tracked belief puts most consecutive particles (offspring
    # of one ancestor lie side by side) in the same cell, and `histogram[cell] += w` would then wait for the
    # store of the particle before. Those two sums run in a register while the cell stays the same and are
    # stored when it changes: the same additions in the same order. (The fine position cells change too often
    # for that to pay: the branch would mispredict.)
    cluster_cell = orientation_cell = np.int64(-1)
    cluster_sum = orientation_sum = 0.0
    for start in range(0, n, BLOCK):
        count = min(BLOCK, n - start)
        stop = start + count
        xs = coordinates[0, start:stop]
        ys = coordinates[1, start:stop]
        ts = coordinates[2, start:stop]
        if copy:
            _deinterleave(poses[start:stop], count, xs, ys, ts)
        _summary_cells(grid, xs, ys, ts, count, cells)
        for p in range(count):
            w = weights[start + p]
            # (Written out rather than called: a helper taking the arrays would cost a reference count per call.)
            cell = np.int64(cells[0, p])
            if cell != cluster_cell:
                if cluster_cell >= 0:
                    cluster[cluster_cell] = cluster_sum
                cluster_cell = cell
                cluster_sum = cluster[cell]
            if cluster_sum == 0.0 and w != 0.0:
                cluster_bits[cell >> 6] |= one << np.uint64(cell & 63)
            cluster_sum += w
            cell = np.int64(cells[1, p])
            if position[cell] == 0.0 and w != 0.0:
                position_bits[cell >> 6] |= one << np.uint64(cell & 63)
            position[cell] += w
            cell = np.int64(cells[2, p])
            if cell != orientation_cell:
                if orientation_cell >= 0:
                    orientation[orientation_cell] = orientation_sum
                orientation_cell = cell
                orientation_sum = orientation[cell]
            if orientation_sum == 0.0 and w != 0.0:
                orientation_bits[cell >> 6] |= one << np.uint64(cell & 63)
            orientation_sum += w
    if cluster_cell >= 0:
        cluster[cluster_cell] = cluster_sum
    if orientation_cell >= 0:
        orientation[orientation_cell] = orientation_sum


@numba.njit(cache=True, inline="always")
def _cluster_groups(grid):
    """The groups cells and shift of `cluster_estimate`, from the summary's parameter array."""
    cells = (
        grid[G_X_MIN],
        grid[G_Y_MIN],
        grid[G_CLUSTER_CELL],
        int(grid[G_CLUSTER_NX]),
        int(grid[G_CLUSTER_NY]),
        int(grid[G_CLUSTER_NT]),
    )
    return cells, (grid[G_RADIUS], grid[G_ANGLE_RADIUS], int(grid[G_ITERATIONS]))


def _summary_estimate_body(
    grid, coordinates, weights, histograms, bitmaps, previous, use_previous, out_mean, out_cov, chunk=0
):
    """`cluster_estimate` from the filled summary: the same mean, covariance and weight. (A template:
    `summary_estimate`, `summary_estimate_fast` and `summary_estimate_chunked` bind its `dominant_cluster`.)"""
    cluster, _, _, cluster_bits, _, _ = _parts(grid, histograms, bitmaps)
    cells, shift = _cluster_groups(grid)
    return dominant_cluster(
        coordinates[0],
        coordinates[1],
        coordinates[2],
        weights,
        _marked_argmax(cluster, cluster_bits),
        cells,
        shift,
        previous,
        use_previous,
        out_mean,
        out_cov,
        chunk,
    )


summary_estimate = variant(_summary_estimate_body, "serial", {"dominant_cluster": _dominant_cluster})
"""`cluster_estimate` from the filled summary (grid, coordinates, weights, histograms, bitmaps, previous,
use_previous, out_mean, out_cov): the same mean, covariance and weight."""


@numba.njit(cache=True)
def summary_entropy(grid, histograms, bitmaps):
    """`grid_entropy` from the filled summary: (position, orientation) bits."""
    _, position, orientation, _, position_bits, orientation_bits = _parts(grid, histograms, bitmaps)
    return _marked_entropy_bits(position, position_bits), _marked_entropy_bits(orientation, orientation_bits)


# -- the same on several threads ------------------------------------------------------------------------------------
# The mean shift's and the covariance's sums taken chunk by chunk (within a chunk in index order, then over
# the chunks in order), the chunks spread over threads: the same estimate for any number of threads, the
# serial one's bit for bit when a chunk holds every particle, otherwise equal to rounding.


_kernel_mean_chunked = variant(_kernel_mean_body, "chunked", {"ONE_CHUNK": False}, parallel=True)


_kernel_covariance_chunked = variant(_kernel_covariance_body, "chunked", {"ONE_CHUNK": False}, parallel=True)


summary_estimate_chunked = variant(
    _summary_estimate_body,
    "chunked",
    {
        "dominant_cluster": variant(
            _dominant_cluster_body,
            "chunked",
            {"kernel_mean": _kernel_mean_chunked, "kernel_covariance": _kernel_covariance_chunked},
        )
    },
)
"""`summary_estimate` with its sums in chunks of `chunk` on several threads (see above): its arguments, then
chunk."""


# Several threads fill the histograms in fixed point (weights in units of 2⁻⁶⁰, one row of `local` per thread),
# where sums in any order are exact: the histograms do not depend on how the chunks fell to the threads, and
# differ from the serial ones by rounding only.
_FIXED = 2.0**60


@numba.njit(cache=True, parallel=True)
def _fill_fixed(grid, poses, weights, coordinates, local, chunk):
    cluster_size, position_size, _ = _layout(grid)
    n = weights.shape[0]
    copy = poses.shape[0] > 0
    for t in numba.prange(max(1, (n + chunk - 1) // chunk)):
        row = numba.get_thread_id()
        cells = np.empty((3, BLOCK), dtype=np.int32)
        for start in range(t * chunk, min(n, (t + 1) * chunk), BLOCK):
            stop = min(start + BLOCK, n, (t + 1) * chunk)
            xs = coordinates[0, start:stop]
            ys = coordinates[1, start:stop]
            ts = coordinates[2, start:stop]
            if copy:
                _deinterleave(poses[start:stop], stop - start, xs, ys, ts)
            _summary_cells(grid, xs, ys, ts, stop - start, cells)
            for p in range(stop - start):
                q = np.int64(weights[start + p] * _FIXED + 0.5)
                local[row, cells[0, p]] += q
                local[row, cluster_size + cells[1, p]] += q
                local[row, cluster_size + position_size + cells[2, p]] += q


@numba.njit(cache=True)
def summary_fill_chunked(grid, poses, weights, coordinates, histograms, bitmaps, local, chunk):
    """`summary_fill` on several threads (`local`: (threads, cells) int64 scratch, zero on entry and on return):
    the same cells, the weights summed in fixed point (equal to rounding)."""
    cluster, position, orientation, cluster_bits, position_bits, orientation_bits = _parts(grid, histograms, bitmaps)
    _clear_marked(cluster, cluster_bits)
    _clear_marked(position, position_bits)
    _clear_marked(orientation, orientation_bits)
    _fill_fixed(grid, poses, weights, coordinates, local, chunk)
    cluster_size, position_size, _ = _layout(grid)
    cluster_words = (cluster_size + 63) // 64
    position_words = (position_size + 63) // 64
    one = np.uint64(1)
    for cell in range(histograms.shape[0]):
        total = 0
        for row in range(local.shape[0]):
            total += local[row, cell]
            local[row, cell] = 0
        if total == 0:
            continue
        histograms[cell] = total / _FIXED
        if cell < cluster_size:
            word, bit = cell >> 6, cell & 63
        elif cell < cluster_size + position_size:
            word, bit = cluster_words + ((cell - cluster_size) >> 6), (cell - cluster_size) & 63
        else:
            offset = cell - cluster_size - position_size
            word, bit = cluster_words + position_words + (offset >> 6), offset & 63
        bitmaps[word] |= one << np.uint64(bit)


# -- the opt-in fast variant ----------------------------------------------------------------------------------------
# With `ParticleFilter(fast=True)`: the serial kernels' one body with fast-math, so that their sums are
# reassociated (vectorized), equal to the serial estimate to rounding.
FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}  # fast-math without assuming no NaN / inf


_kernel_mean_fast = variant(_kernel_mean_body, "fast", {"ONE_CHUNK": True}, fastmath=FAST, error_model="numpy")
_kernel_covariance_fast = variant(
    _kernel_covariance_body, "fast", {"ONE_CHUNK": True}, fastmath=FAST, error_model="numpy"
)


summary_estimate_fast = variant(
    _summary_estimate_body,
    "fast",
    {
        "dominant_cluster": variant(
            _dominant_cluster_body,
            "fast",
            {"kernel_mean": _kernel_mean_fast, "kernel_covariance": _kernel_covariance_fast},
        )
    },
)
"""`summary_estimate` with reassociated sums (equal to rounding)."""


# -- plain numpy references -----------------------------------------------------------------------------------
def _belief_kde(poses, weights, pose, mass: float | None, min_bandwidth) -> tuple:
    """The checked inputs and the kernel density both evaluations share: poses (N, 3), normalised weights (N,),
    pose (3,) and the bandwidths (3,). Raises ValueError on shapes, a pose or particle that is not finite, a mass
    outside (0, 1), bandwidth floors that are not finite and > 0, or weights that are negative or do not sum to a
    positive finite number."""
    poses = np.asarray(poses, dtype=np.float64)
    weights = np.asarray(weights, dtype=np.float64)
    pose = np.asarray(pose, dtype=np.float64)
    if poses.ndim != 2 or poses.shape[1] != 3 or weights.shape != (poses.shape[0],) or pose.shape != (3,):
        raise ValueError(
            f"poses (N, 3), weights (N,) and pose (3,) expected, got {poses.shape}, {weights.shape}, {pose.shape}"
        )
    if not (np.isfinite(poses).all() and np.isfinite(pose).all()):
        raise ValueError("poses and pose must be finite")
    if mass is not None and not (0 < mass < 1):
        raise ValueError(f"mass = {mass!r} must be within (0, 1)")
    floor = np.asarray(min_bandwidth, dtype=np.float64)
    if floor.shape != (3,) or not (np.isfinite(floor).all() and (floor > 0).all()):
        raise ValueError(f"min_bandwidth = {min_bandwidth!r} must be three finite numbers > 0")
    total = float(weights.sum())
    if not (math.isfinite(total) and total > 0) or (weights < 0).any():
        raise ValueError("weights must be >= 0 with a positive finite sum")
    weights = weights / total
    n_effective = 1.0 / float(np.sum(weights**2))
    centre = np.array(
        [
            weights @ poses[:, 0],
            weights @ poses[:, 1],
            math.atan2(weights @ np.sin(poses[:, 2]), weights @ np.cos(poses[:, 2])),
        ]
    )
    residual = poses - centre
    residual[:, 2] = wrap_angles(residual[:, 2])
    spread = np.sqrt(weights @ residual**2)
    bandwidth = np.maximum(spread * n_effective ** (-1.0 / 7.0), floor)  # Scott, d = 3
    return poses, weights, pose, bandwidth


def _kernel_exponents(points: np.ndarray, poses: np.ndarray, bandwidth: np.ndarray) -> np.ndarray:
    difference = points[:, None, :] - poses[None, :, :]
    difference[..., 2] = wrap_angles(difference[..., 2])
    return -0.5 * np.sum((difference / bandwidth) ** 2, axis=-1)


def credible_region_contains(
    poses: np.ndarray,
    weights: np.ndarray,
    pose,
    mass: float = 0.95,
    min_bandwidth: tuple[float, float, float] = (0.005, 0.005, 0.005),
    leave_one_out: bool = True,
) -> bool:
    """Whether `pose` (x, y, θ) lies inside the smallest region holding `mass` of the belief.

    The belief's density is a weighted kernel density estimate over the particles (Gaussian kernels, diagonal
    bandwidths by Scott's rule from the weighted spread, never below `min_bandwidth`, heading differences
    wrapped). The smallest region holding `mass` is where the density exceeds the level at which the particles
    above it hold `mass` of the weight (the highest-density region, estimated from the sample); the pose is
    inside when its density reaches that level. The density at each particle leaves that particle's own kernel
    out (leave-one-out), as the density at a pose that is not a particle has no such term: with it left in, the
    level is biased up and the region holds a pose drawn from the particles' own distribution less often than
    `mass`, the more so the fewer the particles (`tests/test_estimate.py` checks the coverage at 30, 100 and
    200 particles; `leave_one_out=False` is the biased estimate, kept for comparison). O(N²): meant for
    evaluation, not for the robot's loop.
    """
    poses, weights, pose, bandwidth = _belief_kde(poses, weights, pose, mass, min_bandwidth)

    def density(points: np.ndarray) -> np.ndarray:
        return np.exp(_kernel_exponents(points, poses, bandwidth)) @ weights

    at_particles = density(poses)
    others = 1.0 - weights  # the weight of the other particles, for leaving one out
    alone = (others <= 1e-9) | (not leave_one_out)  # a particle holding (nearly) all of the weight keeps its kernel
    at_particles = np.where(alone, at_particles, (at_particles - weights) / np.where(alone, 1.0, others))
    order = np.argsort(-at_particles, kind="stable")
    held = np.cumsum(weights[order])
    level = at_particles[order[min(int(np.searchsorted(held, mass)), order.size - 1)]]
    return bool(density(pose[None, :])[0] >= level)


def belief_log_density(
    poses: np.ndarray, weights: np.ndarray, pose, min_bandwidth: tuple[float, float, float] = (0.005, 0.005, 0.005)
) -> float:
    """The log of the belief's density at `pose` (x, y, θ), in log(1 / (m²·rad)): the logarithmic score.

    The density is the kernel density estimate of `credible_region_contains` (same bandwidths), normalised: each
    Gaussian kernel integrates to one over the plane and the real line of headings (a kernel wider than about a
    radian loses the mass that falls past ±π, which lowers the score of a cloud that wide). Evaluated at the true
    pose it is a proper score: it rewards a belief that is both tight and holds the truth, where
    `credible_region_contains` alone rewards any belief wide enough. Computed in the log domain, so it is finite
    however far the pose lies from the particles. O(N): meant for evaluation.

    Raises
    ------
    ValueError
        If the shapes are not (N, 3), (N,) and (3,), a pose or particle is not finite, the weights are negative
        or do not sum to a positive finite number, or `min_bandwidth` is not three finite numbers > 0.
    """
    poses, weights, pose, bandwidth = _belief_kde(poses, weights, pose, None, min_bandwidth)
    exponents = _kernel_exponents(pose[None, :], poses, bandwidth)[0]
    with np.errstate(divide="ignore"):
        terms = exponents + np.log(weights)
    top = float(terms.max())
    log_sum = top + math.log(float(np.exp(terms - top).sum()))
    return log_sum - float(np.log(bandwidth).sum()) - 1.5 * math.log(2.0 * math.pi)
