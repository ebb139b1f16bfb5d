"""``Result.coordinate_names`` in result files: written to the metadata of every format and read
back; a file of an earlier version (no names) reads as None; a malformed list (not a list of
strings, the wrong length, an overlong or control-character name) is one InputError, as is a
Result whose names the reader would refuse, before anything is written."""
import io
import json

import numpy as np
import pytest

import ldaspark
from ldaspark import load_result, save_result
from ldaspark.core.errors import InputError, LdasparkError
from ldaspark.core.resultio import MAX_NAME_CHARS

try:
    import h5py
except ImportError:                 # .h5 needs the optional h5py; .json and .npz run without it
    h5py = None

FORMATS = ["json", "npz", pytest.param("h5", marks=pytest.mark.skipif(h5py is None, reason="needs h5py"))]


@pytest.fixture(scope="module")
def run():
    return ldaspark.integrate("turntable", "gauss-2", n_steps=3, h=0.1, engine="generic")


def _edit_metadata(path, ext, edit):
    """Rewrite the metadata JSON of a result file with ``edit(dict)``, as another writer could."""
    if ext == "json":
        d = json.loads(path.read_text())
        edit(d)
        path.write_text(json.dumps(d))
    elif ext == "npz":
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        md = json.loads(str(arrays.pop("metadata")))
        edit(md)
        buf = io.BytesIO()
        np.savez(buf, metadata=np.array(json.dumps(md)), **arrays)
        path.write_bytes(buf.getvalue())
    else:
        with h5py.File(path, "r+") as f:
            md = json.loads(f["metadata"][()].decode())
            edit(md)
            del f["metadata"]
            f.create_dataset("metadata", data=np.bytes_(json.dumps(md).encode()))


@pytest.mark.parametrize("ext", FORMATS)
def test_the_names_round_trip_and_an_old_file_reads_as_none(run, tmp_path, ext):
    assert run.coordinate_names == ["x", "y", "theta", "phi"]
    p = tmp_path / f"r.{ext}"
    save_result(run, p)
    assert load_result(p).coordinate_names == run.coordinate_names
    # a file of an earlier version has no names: still read, with names None (and the rest)
    _edit_metadata(p, ext, lambda md: md.pop("coordinate_names"))
    old = load_result(p)
    assert old.coordinate_names is None and np.array_equal(old.q, run.q)


BAD = {
    "a string": "x y theta phi",
    "too few": ["x", "y", "theta"],
    "too many": ["x", "y", "theta", "phi", "psi"],
    "a number": ["x", "y", 3, "phi"],
    "an empty name": ["x", "", "theta", "phi"],
    "a line break": ["x", "y\nz", "theta", "phi"],
    "overlong": ["x", "y" * (MAX_NAME_CHARS + 1), "theta", "phi"],
    "a dict": {"0": "x"},
}


@pytest.mark.parametrize("ext", FORMATS)
@pytest.mark.parametrize("case", sorted(BAD))
def test_malformed_names_in_a_file_are_one_input_error(run, tmp_path, ext, case):
    p = tmp_path / f"r.{ext}"
    save_result(run, p)
    _edit_metadata(p, ext, lambda md: md.update(coordinate_names=BAD[case]))
    with pytest.raises(InputError, match="coordinate_names") as ei:
        load_result(p)
    assert len(str(ei.value).splitlines()) == 1


@pytest.mark.parametrize("ext", FORMATS)
def test_names_at_the_bounds_are_read(run, tmp_path, ext):
    """Control of the malformed cases: the longest name allowed, and a name that looks like code
    (a name is only a string: compared and printed, never evaluated), are read as written."""
    p = tmp_path / f"r.{ext}"
    save_result(run, p)
    names = ["x", "y" * MAX_NAME_CHARS, "__import__('os').getcwd()", "θ"]
    _edit_metadata(p, ext, lambda md: md.update(coordinate_names=names))
    assert load_result(p).coordinate_names == names


@pytest.mark.parametrize("ext", FORMATS)
def test_the_writer_refuses_names_the_reader_would_refuse(run, tmp_path, ext):
    import copy
    bad = copy.copy(run)
    bad.coordinate_names = ["x", "y"]                    # two names for n = 4
    p = tmp_path / f"r.{ext}"
    with pytest.raises(LdasparkError, match="coordinate_names has 2 names for n = 4"):
        save_result(bad, p)
    assert not p.exists()
    bad.coordinate_names = None                          # control: a Result without names is written
    save_result(bad, p)
    assert load_result(p).coordinate_names is None
