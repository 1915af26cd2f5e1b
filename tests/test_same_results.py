"""Moving code must not move results: the walk demo, the replay and the filter's variants (threads, fast-math,
a stateful motion model with multinomial resampling, latency) give the arrays recorded in
`tests/data/same_results.npz`, bit for bit (`tests/same_results.py` says how they were made). The fast-math
variant (`fast=True`) promises results to rounding only, and is compared so: LLVM may contract and reassociate
its arithmetic differently when the code around a kernel changes."""

import numpy as np
import pytest

import same_results


@pytest.fixture(scope="module")
def recorded():
    with np.load(same_results.PATH) as data:
        return {name: data[name] for name in data.files}


@pytest.mark.parametrize("case", sorted(same_results.CASES))
def test_same_results_bit_for_bit(recorded, case):
    arrays = same_results.CASES[case]()
    assert {f"{case}/{key}" for key in arrays} == {name for name in recorded if name.startswith(case + "/")}
    same_machine = str(recorded["__machine__"]) == same_results.machine()
    exact = same_machine and case not in same_results.TO_ROUNDING
    for key, value in arrays.items():
        expected = recorded[f"{case}/{key}"]
        assert value.shape == expected.shape and value.dtype == expected.dtype, key
        if exact:
            # the bits themselves: NaN where NaN, -0.0 where -0.0
            assert np.asarray(value).tobytes() == expected.tobytes(), f"{case}/{key} differs"
        else:
            # another processor or numeric library may round a libm call differently in the last place; fast-math
            # kernels are contracted and reassociated as LLVM sees fit for the code around them
            np.testing.assert_allclose(value, expected, rtol=1e-9, atol=1e-12, err_msg=f"{case}/{key}")
