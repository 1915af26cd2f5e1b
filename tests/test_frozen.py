"""numerics.frozen: copies of a holder freeze again exactly the arrays that were read-only in the original."""

import copy
import pickle
from dataclasses import dataclass

import numpy as np
import pytest

from numerics.frozen import frozen_paths, keeps_arrays_frozen


def _frozen(values):
    array = np.array(values, dtype=np.float64)
    array.flags.writeable = False
    return array


@keeps_arrays_frozen
@dataclass(frozen=True, eq=False)
class Holder:
    table: np.ndarray
    pair: tuple
    buffer: np.ndarray
    name: str = "h"


COPIES = [copy.copy, copy.deepcopy, lambda h: pickle.loads(pickle.dumps(h))]


@pytest.mark.parametrize("clone", COPIES, ids=["copy", "deepcopy", "pickle"])
def test_a_copy_freezes_what_was_read_only_and_nothing_else(clone):
    shared = _frozen([1.0, 2.0])
    holder = Holder(_frozen([[1.0, 2.0]]), (shared, np.zeros(2), (3, _frozen([4.0]))), np.zeros(3))
    twin = clone(holder)
    assert not twin.table.flags.writeable and not twin.pair[0].flags.writeable
    assert not twin.pair[2][1].flags.writeable
    assert twin.buffer.flags.writeable and twin.pair[1].flags.writeable  # a work buffer stays writable
    np.testing.assert_array_equal(twin.table, holder.table)
    assert twin.name == "h" and frozen_paths(twin.pair) == frozen_paths(holder.pair) == [(0,), (2, 1)]
    twin.buffer[0] = 5.0
    assert holder.buffer[0] == 0.0 or clone is copy.copy  # (a shallow copy shares its arrays)


def test_a_class_with_its_own_state_methods_is_refused():
    class Own:
        def __getstate__(self):
            return {}

    with pytest.raises(TypeError, match="__getstate__"):
        keeps_arrays_frozen(Own)
