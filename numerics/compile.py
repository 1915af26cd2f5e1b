"""One source, several compiled kernels: variants that differ by compile flags, or by the kernels they call.

    from numerics.compile import variant
    sincos_rows_fast = variant(sincos_rows_source, "fast", fastmath=FAST, error_model="numpy")
    step = variant(step_template, key, {"score": model_score})      # `score` bound in the template's globals

`variant` compiles a plain function (`numba.njit(cache=True, **options)`) as "name[key]", so that each variant
has its own entry in numba's cache. With `names`, the template's global names are bound to those values in a
copy of its module's globals taken at the call (so call it once the module is loaded): this is how the
filter's fused step (`mcl.step.fused_step`) is compiled once per kind of sensor model, from one source, with
the model's kernels inlined. Without `names` the variant reads its module's globals as any kernel does.

numba keys a cached variant by its source file's stamp and bytecode, not by the values bound in its globals:
a key must therefore name what was bound (its qualified name and a hash of its bytecode, as
`mcl.step.fused_step` does), so that different bindings never share a cache entry.
"""

from __future__ import annotations

import types

import numba


def variant(template, key: str, names: dict | None = None, **options):
    """`template` compiled with numba.njit(cache=True, **options) as "template[key]", with `names` (if any)
    bound in its globals."""
    namespace = template.__globals__
    if names:
        namespace = dict(namespace)
        namespace.update(names)
    function = types.FunctionType(template.__code__, namespace, template.__name__, template.__defaults__)
    function.__qualname__ = f"{template.__name__}[{key}]"
    function.__module__ = template.__module__
    function.__doc__ = template.__doc__
    return numba.njit(cache=True, **options)(function)
