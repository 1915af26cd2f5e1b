"""Spreading work over threads: chunk sizes that split evenly and do not depend on the number of threads.

from numerics.chunks import balanced_chunk, CHUNK
"""

import numba

CHUNK = 8192  # draws per chunk of `parallel_uniforms`, about (the numbers do not depend on the chunks)


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
