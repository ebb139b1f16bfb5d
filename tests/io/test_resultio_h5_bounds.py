"""The .h5 result file at its edges (``ldaspark.core.resultio``): the run's scalars stored as
HDF5 attributes of their own type for other HDF5 tools (an integer within int64 as an integer,
only one beyond it as its JSON text), and the object count bounded at ``MAX_H5_OBJECTS``
(that many taken, one more refused)."""
from __future__ import annotations

import pytest

import ldaspark
from ldaspark.core import resultio
from ldaspark.core.errors import InputError

h5py = pytest.importorskip("h5py")


def test_integer_attributes_are_integers_within_int64(tmp_path):
    """dps = 30 is an int64: stored as the integer 30, not the text "30" (status 0 fits either
    way, so the positive integer is what tells)."""
    res = ldaspark.integrate("skate", "gauss-1", n_steps=2, h=0.1, engine="generic", dps=30)
    p = tmp_path / "r.h5"
    resultio.save_result(res, p)
    with h5py.File(p, "r") as f:
        dps = f.attrs["dps"]
        assert not isinstance(dps, (str, bytes)) and int(dps) == 30
        assert f.attrs["method"] == "gauss-1" and int(f.attrs["status"]) == 0
    assert resultio.load_result(p).dps == 30


def _groups(path, n):
    with h5py.File(path, "w") as f:
        for i in range(n):
            f.create_group(f"g{i}")


def test_the_object_count_is_bounded_at_MAX_H5_OBJECTS(tmp_path):
    n = resultio.MAX_H5_OBJECTS
    _groups(tmp_path / "at.h5", n)
    with h5py.File(tmp_path / "at.h5", "r") as f:
        resultio._h5_check_tree(f)                      # exactly the bound: taken
    _groups(tmp_path / "over.h5", n + 1)
    with h5py.File(tmp_path / "over.h5", "r") as f, pytest.raises(InputError, match=f"more than {n} objects"):
        resultio._h5_check_tree(f)
