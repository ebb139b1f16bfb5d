"""One reader policy for every result format, and what the writer writes the reader reads.

* HDF5: external links, soft links, external raw storage, virtual datasets, committed datatypes,
  variable-length strings and filters other than deflate / shuffle / fletcher32 are refused
  before any data is read (a FIFO they name is never opened: checked in a subprocess with a
  timeout). Each attack file is first read naively with h5py as a control: it really does
  deliver the outside data.
* .npz: dtype whitelist with non-zero item size (U0, S0, V0 claiming 10^12 elements cost nothing
  on disk), object / datetime / void / complex / bool arrays refused from the header.
* Non-finite values anywhere (arrays, events, dense output, h, params, stats) are refused at
  write time in all three formats; every finite field, extremes included, round-trips exactly.
* ``save_result`` / ``load_result`` arguments: None, 3, True, bytes, a NUL in the path, an int
  file descriptor: one InputError (the descriptor is neither read nor closed)."""
import io
import json
import os
import subprocess
import sys
import zipfile

import numpy as np
import pytest
from hypothesis import given, strategies as st

import ldaspark
from ldaspark import load_result, save_result
from ldaspark.core.errors import InputError

from run_helpers import time_bound

h5py = pytest.importorskip("h5py")
FORMATS = ("json", "npz", "h5")
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _down(t, q, v):
    return q[0] + 0.1


_down.direction = -1


@pytest.fixture(scope="module")
def res():
    """A generic run with psi, one event and collocation dense output."""
    r = ldaspark.integrate("skate", "gauss-2", t_span=(0, 1), h=0.1, dense_output=True, events=[_down],
                           engine="generic")
    assert r.psi is not None and len(r.t_events[0]) == 1 and r.sol is not None
    return r


@pytest.fixture(scope="module")
def good(res, tmp_path_factory):
    d = tmp_path_factory.mktemp("good")
    save_result(res, d / "good.h5")
    save_result(res, d / "good.npz")
    return d


def refused(path, match):
    with time_bound(60), pytest.raises(InputError, match=match) as ei:
        load_result(path)
    assert "\n" not in str(ei.value)


def _copy(res, **change):
    import copy
    r = copy.copy(res)
    for k, v in change.items():
        setattr(r, k, v)
    return r


# --- arguments ---------------------------------------------------------------------------------
@pytest.mark.parametrize("bad, match", [(None, "NoneType"), (3, "integer 3"), (True, "integer"), (2.5, "float"),
                                        (b"r.json", "bytes"), ("a\0b.json", "NUL"), ("", "empty"),
                                        (["r.json"], "list")])
def test_path_arguments_are_checked(res, tmp_path, bad, match):
    with pytest.raises(InputError, match=match):
        save_result(res, bad)
    with pytest.raises(InputError, match=match):
        load_result(bad)
    assert os.listdir(tmp_path) == []
    save_result(res, str(tmp_path / "ok.json"))                 # control: str and PathLike
    assert load_result(tmp_path / "ok.json").q.shape == res.q.shape


def test_a_file_descriptor_is_neither_read_nor_closed(res, tmp_path):
    p = tmp_path / "r.npz"
    save_result(res, p)
    fd = os.open(p, os.O_RDONLY)
    try:
        with pytest.raises(InputError, match="file descriptors are not accepted"):
            load_result(fd)
        with pytest.raises(InputError, match="file descriptors are not accepted"):
            save_result(res, fd)
        assert os.fstat(fd).st_size == p.stat().st_size and os.lseek(fd, 0, os.SEEK_CUR) == 0   # still open, unread
    finally:
        os.close(fd)


@pytest.mark.parametrize("bad", [None, "result", {"t": [0.0]}, 3])
def test_save_result_needs_a_result(tmp_path, bad):
    with pytest.raises(InputError, match="needs a Result"):
        save_result(bad, tmp_path / "r.json")
    assert not (tmp_path / "r.json").exists()


# --- HDF5: nothing outside the file -------------------------------------------------------------
def _variant(good, tmp_path, name, make):
    import shutil
    p = tmp_path / name
    shutil.copy(good / "good.h5", p)
    with h5py.File(p, "a") as f:
        make(f)
    return p


def _outside(tmp_path, q):
    """A regular HDF5 file and a raw file of the attacker, both holding q + 1000."""
    src = tmp_path / "outside.h5"
    with h5py.File(src, "w") as f:
        f["q"] = q + 1000
    raw = tmp_path / "outside.bin"
    raw.write_bytes(np.ascontiguousarray(q + 1000, dtype="<f8").tobytes())
    return src, raw


def _attacks(q, src, raw):
    def ext_link(f):
        del f["q"]
        f["q"] = h5py.ExternalLink(str(src), "/q")

    def soft_link(f):
        del f["q"]
        f["q"] = h5py.SoftLink("/v")

    def ext_storage(f):
        del f["q"]
        f.create_dataset("q", shape=q.shape, dtype="<f8", external=[(str(raw), 0, h5py.h5f.UNLIMITED)])

    def virtual(f):
        del f["q"]
        lay = h5py.VirtualLayout(shape=q.shape, dtype="f8")
        lay[:] = h5py.VirtualSource(str(src), "q", shape=q.shape)
        f.create_virtual_dataset("q", lay, fillvalue=0)

    def hidden_link(f):                       # not a name the reader uses: refused all the same
        f.create_group("a/b")["x"] = h5py.ExternalLink(str(src), "/q")

    def committed(f):
        f["q_type"] = np.dtype("f8")

    def vlen(f):
        del f["q"]
        f.create_dataset("q", data=np.array(["1.0"] * q.size, dtype=object).reshape(q.shape),
                         dtype=h5py.string_dtype())

    def lzf(f):
        data = f["q"][()]
        del f["q"]
        f.create_dataset("q", data=data, compression="lzf")
    return {"external link": (ext_link, "external link"), "soft link": (soft_link, "soft link"),
            "external storage": (ext_storage, "external files"), "virtual": (virtual, "virtual dataset"),
            "hidden link": (hidden_link, "external link"), "committed datatype": (committed, "Datatype"),
            "vlen strings": (vlen, "variable-length"), "lzf filter": (lzf, "filter 32000")}


@pytest.mark.parametrize("attack", ["external link", "soft link", "external storage", "virtual", "hidden link",
                                    "committed datatype", "vlen strings", "lzf filter"])
def test_h5_that_reaches_outside_is_refused(res, good, tmp_path, attack):
    src, raw = _outside(tmp_path, res.q)
    make, match = _attacks(res.q, src, raw)[attack]
    p = _variant(good, tmp_path, "attack.h5", make)
    if attack in ("external link", "external storage", "virtual"):
        with h5py.File(p, "r") as f:                # control: h5py alone hands over the outside data
            assert np.array_equal(f["q"][()], res.q + 1000)
    if attack == "soft link":
        with h5py.File(p, "r") as f:
            assert np.array_equal(f["q"][()], res.v)
    refused(p, match)


def test_h5_compressed_with_builtin_filters_still_loads(res, good, tmp_path):
    def gz(f):
        data = f["q"][()]
        del f["q"]
        f.create_dataset("q", data=data, compression="gzip", shuffle=True, fletcher32=True, chunks=True)
    p = _variant(good, tmp_path, "gz.h5", gz)
    assert np.array_equal(load_result(p).q, res.q)


_FIFO_SCRIPT = r"""
import sys, numpy as np, h5py
sys.path.insert(0, sys.argv[1])
from ldaspark import load_result
from ldaspark.core.errors import InputError
good, d = sys.argv[2], sys.argv[3]
fifo = d + "/fifo"
import os, shutil
os.mkfifo(fifo)
q = load_result(good).q
def variant(name, make):
    p = d + "/" + name
    shutil.copy(good, p)
    with h5py.File(p, "a") as f:
        del f["q"]
        make(f)
    return p
def vds(f):
    lay = h5py.VirtualLayout(shape=q.shape, dtype="f8")
    lay[:] = h5py.VirtualSource(fifo, "q", shape=q.shape)
    f.create_virtual_dataset("q", lay, fillvalue=0)
files = [variant("l.h5", lambda f: f.__setitem__("q", h5py.ExternalLink(fifo, "/q"))),
         variant("e.h5", lambda f: f.create_dataset("q", shape=q.shape, dtype="f8",
                                                    external=[(fifo, 0, h5py.h5f.UNLIMITED)])),
         variant("v.h5", vds)]
for p in files:
    try:
        load_result(p)
        print("LOADED", p)
    except InputError as exc:
        print("refused:", exc)
"""


def test_a_fifo_behind_a_link_storage_or_virtual_dataset_is_never_opened(good, tmp_path):
    """Before: the external link, external storage or virtual dataset opened the FIFO and
    blocked forever. In a subprocess: a blocked open() in the HDF5 library cannot be interrupted."""
    p = subprocess.run([sys.executable, "-c", _FIFO_SCRIPT, ROOT, str(good / "good.h5"), str(tmp_path)],
                       capture_output=True, text=True, timeout=120)
    lines = p.stdout.splitlines()
    assert p.returncode == 0 and len(lines) == 3 and all(x.startswith("refused:") for x in lines), (p.stdout, p.stderr)
    assert "external link" in lines[0] and "external files" in lines[1] and "virtual" in lines[2]


# --- .npz: dtype whitelist, item size, header before data --------------------------------------
def _npz_with(good, tmp_path, name, header=None, member=None):
    """good.npz with q replaced by a bare header (no data) or by the array ``member``."""
    z = dict(np.load(good / "good.npz"))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for k in z:
            b = io.BytesIO()
            if k == "q" and header is not None:
                np.lib.format.write_array_header_1_0(b, header)
            else:
                np.save(b, member if k == "q" and member is not None else z[k], allow_pickle=True)
            zf.writestr(k + ".npy", b.getvalue())
    p = tmp_path / name
    p.write_bytes(buf.getvalue())
    return p


@pytest.mark.parametrize("descr, match", [("<U0", "zero item size"), ("|S0", "zero item size"),
                                          ("|V0", "dtype \\|V0: not a result array")])
def test_npz_zero_width_dtypes_are_refused(good, tmp_path, descr, match):
    hdr = {"descr": descr, "fortran_order": False, "shape": (10 ** 12,)}
    p = _npz_with(good, tmp_path, "zero.npz", header=hdr)
    # control: numpy accepts the header, and its claimed bytes (0) pass a size bound on its own
    with zipfile.ZipFile(p) as zf, zf.open("q.npy") as f:
        np.lib.format.read_magic(f)
        shape, _, dtype = np.lib.format.read_array_header_1_0(f)
    assert shape == (10 ** 12,) and dtype.itemsize == 0
    refused(p, match)


@pytest.mark.parametrize("member, match", [
    (np.array([object(), 1], dtype=object), "object array"),
    (np.zeros((5, 3), dtype="M8[s]"), "dtype datetime64"),
    (np.zeros((5, 3), dtype="V8"), "dtype \\|V8"),
    (np.zeros((5, 3), dtype=complex), "dtype complex128"),
    (np.zeros((5, 3), dtype=bool), "dtype bool"),
])
def test_npz_dtypes_outside_the_whitelist_are_refused(good, tmp_path, member, match):
    p = _npz_with(good, tmp_path, "bad.npz", member=member)
    refused(p, match)


def test_npz_metadata_must_be_one_json_string(good, tmp_path):
    z = dict(np.load(good / "good.npz"))
    for name, md in (("two", np.array([str(z["metadata"])] * 2)), ("num", np.array(3.0))):
        p = tmp_path / f"{name}.npz"
        np.savez(p, **dict(z, metadata=md))
        refused(p, "metadata")


def test_string_trajectories_of_an_mpmath_run_still_load(tmp_path):
    mp = ldaspark.integrate("skate", "gauss-2", t_span=(0, 0.1), h="0.05", dps=20)
    for ext in FORMATS:
        save_result(mp, tmp_path / f"mp.{ext}")
        back = load_result(tmp_path / f"mp.{ext}")
        assert back.dps == 20 and back.q.dtype == object


# --- what the writer writes the reader reads ---------------------------------------------------
def _setters():
    def arr(name, idx):
        def f(r, x):
            a = np.array(getattr(r, name), dtype=float)
            a[idx] = x
            return _copy(r, **{name: a})
        return f

    def ev(name):
        def f(r, x):
            lst = [np.array(a, float) for a in getattr(r, name)]
            lst[0].flat[0] = x
            return _copy(r, **{name: lst})
        return f

    def dense(attr):
        def f(r, x):
            import copy
            sol = copy.copy(r.sol)
            a = np.array(getattr(sol, attr), float)
            # a finite node stays between its neighbours (the reader wants increasing nodes)
            a.flat[1] = (a[0] + a[2]) / 2 if attr == "t" and np.isfinite(x) else x
            setattr(sol, attr, a)
            return _copy(r, sol=sol)
        return f
    return {"t": arr("t", 3), "q": arr("q", (2, 0)), "v": arr("v", (1, 1)), "energy": arr("energy", 0),
            "constraint": arr("constraint", (4, 0)), "psi": arr("psi", (0, 1, 0)),
            "t_events": ev("t_events"), "q_events": ev("q_events"), "v_events": ev("v_events"),
            "dense_q": dense("q"), "dense_v": dense("v"), "dense_V": dense("V"), "dense_t": dense("t"),
            "h": lambda r, x: _copy(r, h=x),
            "params": lambda r, x: _copy(r, params={"mu": x}),
            "stats": lambda r, x: _copy(r, stats=dict(r.stats, max_residual=x)),
            "stats nested": lambda r, x: _copy(r, stats=dict(r.stats, history=[1.0, {"worst": x}]))}


@pytest.mark.parametrize("ext", FORMATS)
@pytest.mark.parametrize("field", list(_setters()))
@pytest.mark.parametrize("value", [float("nan"), float("inf"), -float("inf")])
def test_every_non_finite_field_is_refused_at_write_time_in_every_format(res, tmp_path, ext, field, value):
    bad = _setters()[field](res, value)
    with pytest.raises(InputError, match="refusing to write") as ei:
        save_result(bad, tmp_path / f"bad.{ext}")
    assert "\n" not in str(ei.value)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("ext", FORMATS)
@pytest.mark.parametrize("field", list(_setters()))
def test_every_finite_field_round_trips_in_every_format(res, tmp_path, ext, field):
    """The control of the test above: the same field set to a finite value is written and read
    back exactly (extremes of float64 included)."""
    for x in (1.7976931348623157e308, 5e-324, -0.0, 0.25):
        if field == "h" and x <= 0:
            continue
        r = _setters()[field](res, x)
        p = tmp_path / f"ok.{ext}"
        save_result(r, p)
        back = load_result(p)
        for name in ("t", "q", "v", "energy", "constraint", "psi"):
            a, b = np.asarray(getattr(r, name), float), getattr(back, name)
            assert a.shape == b.shape and np.array_equal(a, b) and \
                np.array_equal(np.signbit(a), np.signbit(b)), (name, x)
        for name in ("t_events", "q_events", "v_events"):
            assert all(np.array_equal(a, b) for a, b in zip(getattr(r, name), getattr(back, name)))
        for k in ("t", "q", "v", "c", "V"):
            assert np.array_equal(getattr(r.sol, k), getattr(back.sol, k)), k
        assert (back.h, back.params, back.stats) == (r.h, r.params, r.stats)
        if field == "stats":
            assert np.signbit(back.stats["max_residual"]) == np.signbit(x)


@pytest.mark.parametrize("ext", FORMATS)
def test_stats_of_every_json_kind_round_trip(res, tmp_path, ext):
    stats = {"steps": 2 ** 62, "neg": -7, "ok": True, "none": None, "path": "generic", "tiny": 5e-324,
             "nested": {"a": [1, 2.5, "x", [False]]}, "np_int": np.int64(3), "np_float": np.float64(0.5),
             "np_bool": np.bool_(True)}
    p = tmp_path / f"s.{ext}"
    save_result(_copy(res, stats=stats), p)
    back = load_result(p).stats
    assert back == {"steps": 2 ** 62, "neg": -7, "ok": True, "none": None, "path": "generic", "tiny": 5e-324,
                    "nested": {"a": [1, 2.5, "x", [False]]}, "np_int": 3, "np_float": 0.5, "np_bool": True}
    assert type(back["np_bool"]) is bool and type(back["steps"]) is int


@pytest.mark.parametrize("ext", FORMATS)
def test_an_ensembles_counters_round_trip(tmp_path, ext):
    ens = ldaspark.integrate("particle", "gauss-1", n_steps=3, h=0.1, q0=[[1, 0, 0], [2, 0, 0]],
                             v0=[[0, 1, 0], [0, 2, 0]], engine="generic")
    if ext == "json":
        with pytest.raises(InputError, match="ensemble"):
            save_result(ens, tmp_path / "e.json")
        return
    save_result(ens, tmp_path / f"e.{ext}")
    back = load_result(tmp_path / f"e.{ext}")
    for c in ("nfev", "njev", "nlu", "newton_iterations"):
        assert np.array_equal(np.asarray(getattr(back, c)), np.asarray(getattr(ens, c))), c


_finite_json = st.recursive(
    st.none() | st.booleans() | st.integers(-2 ** 63, 2 ** 63) | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=4),
    lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=3), c, max_size=3), max_leaves=6)


@given(stats=st.dictionaries(st.text(max_size=4), _finite_json, max_size=4),
       poison=st.sampled_from([None, float("nan"), float("inf"), -float("inf")]))
def test_stats_property_one_policy_for_three_formats(res, tmp_path_factory, stats, poison):
    d = tmp_path_factory.mktemp("prop")
    if poison is not None:
        stats = dict(stats, poisoned=[0, {"x": poison}])
    for ext in FORMATS:
        p = d / f"r.{ext}"
        if poison is not None:
            with pytest.raises(InputError, match="refusing to write"):
                save_result(_copy(res, stats=stats), p)
            assert not p.exists()
            continue
        save_result(_copy(res, stats=stats), p)
        assert load_result(p).stats == stats


@pytest.mark.parametrize("ext", FORMATS)
def test_a_file_claiming_non_finite_stats_is_refused_by_every_reader(res, good, tmp_path, ext):
    """The reader's side of the policy: non-finite stats written by another program."""
    p = tmp_path / f"inf.{ext}"
    if ext == "json":
        save_result(res, p)
        d = json.loads(p.read_text())
        d["stats"]["max_residual"] = float("inf")
        p.write_text(json.dumps(d))
    elif ext == "npz":
        z = dict(np.load(good / "good.npz"))
        md = json.loads(str(z["metadata"]))
        md["stats"]["max_residual"] = float("inf")
        np.savez(p, **dict(z, metadata=np.array(json.dumps(md))))
    else:
        import shutil
        shutil.copy(good / "good.h5", p)
        with h5py.File(p, "a") as f:
            md = json.loads(bytes(f["metadata"][()]))
            md["stats"]["max_residual"] = float("inf")
            del f["metadata"]
            f["metadata"] = np.bytes_(json.dumps(md).encode())
    refused(p, "not a finite")


@pytest.mark.parametrize("name, shape, match", [("dense_q", (3, 3), "dense_q has shape"),
                                                ("dense_V", (2, 2, 3), "dense_V has shape"),
                                                ("dense_v", (3, 3), "dense_v has shape"),
                                                ("q_events_0", (4, 3), "q_events_0 has shape"),
                                                ("dense_t", (1,), "at least two")])
def test_inconsistent_events_and_dense_data_are_refused(good, tmp_path, name, shape, match):
    z = dict(np.load(good / "good.npz"))
    p = tmp_path / "bad.npz"
    np.savez(p, **dict(z, **{name: np.zeros(shape)}))
    refused(p, match)
    p2 = tmp_path / "ok.npz"                        # control: the file as written loads and evaluates
    np.savez(p2, **z)
    back = load_result(p2)
    assert np.all(np.isfinite(back.sol(0.55)[0]))


def test_a_file_written_before_the_grid_correction_reads_as_it_was_saved(res, good, tmp_path):
    """A file of the stage polynomial without ``dense_v`` (written before the correction to the
    grid) loads as the uncorrected polynomial it was saved with; the file as written now (with
    ``dense_v``) reproduces the saved v at the grid. Control: the two differ there."""
    from ldaspark.core.dense import CollocationDense
    z = dict(np.load(good / "good.npz"))
    assert "dense_v" in z and "dense_c" in z
    p = tmp_path / "old.npz"
    np.savez(p, **{k: a for k, a in z.items() if k != "dense_v"})
    old, new = load_result(p), load_result(good / "good.npz")
    assert isinstance(old.sol, CollocationDense) and old.sol.v is None and new.sol.v is not None
    tt = np.linspace(0, 1, 23)
    want = CollocationDense(res.sol.t, res.sol.q, res.sol.c, res.sol.V)(tt)
    assert all(np.array_equal(a, b) for a, b in zip(old.sol(tt), want))
    assert all(np.array_equal(a, b) for a, b in zip(new.sol(tt), res.sol(tt)))
    assert np.abs(new.sol(res.t)[1] - res.v).max() < 1e-14
    assert np.abs(old.sol(res.t)[1] - res.v).max() > 1e-5          # control


@pytest.mark.parametrize("change, match", [(dict(nfev="abc"), "nfev"), (dict(njev=-1), "njev"),
                                           (dict(nlu=True), "nlu"), (dict(h=[0.1]), "h must be"),
                                           (dict(version=3), "version")])
def test_metadata_field_types_are_checked(good, tmp_path, change, match):
    z = dict(np.load(good / "good.npz"))
    md = dict(json.loads(str(z["metadata"])), **change)
    p = tmp_path / "bad.npz"
    np.savez(p, **dict(z, metadata=np.array(json.dumps(md))))
    refused(p, match)


@pytest.mark.parametrize("ext", FORMATS)
def test_dense_data_the_reader_would_refuse_are_not_written(res, tmp_path, ext):
    import copy
    sol = copy.copy(res.sol)
    sol.t = np.array(sol.t)
    sol.t[[1, 2]] = sol.t[[2, 1]]                    # nodes out of order
    with pytest.raises(InputError, match="refusing to write a result that the reader would refuse"):
        save_result(_copy(res, sol=sol), tmp_path / f"r.{ext}")
    sol.V = res.sol.V[:-1]                           # one step's stage velocities missing
    sol.t = res.sol.t
    with pytest.raises(InputError, match="dense_V has shape"):
        save_result(_copy(res, sol=sol), tmp_path / f"r.{ext}")
    assert os.listdir(tmp_path) == []


def test_h5_metadata_is_a_fixed_length_string_checked_before_reading(res, good, tmp_path):
    """Read from a scalar dataset of one fixed-length string (its size is known before it is
    read): a variable-length string lives in the global heap, and a corrupt heap entry made the
    HDF5 library loop forever while reading it (found by the byte-flip fuzz below, on files of
    the earlier writer)."""
    with h5py.File(good / "good.h5", "r") as f:
        ds = f["metadata"]
        assert ds.shape == () and ds.dtype.kind == "S" and json.loads(bytes(ds[()]))["method"] == "gauss-2"
    import shutil
    legacy = tmp_path / "legacy.h5"                  # files of the earlier writer still load
    shutil.copy(good / "good.h5", legacy)
    with h5py.File(legacy, "a") as f:
        del f["metadata"]
        assert h5py.check_string_dtype(f.attrs.get_id("metadata").dtype).length is None
    assert np.array_equal(load_result(legacy).q, res.q)
    for name, make in (("vlen", lambda f: f.create_dataset("metadata", data="{}", dtype=h5py.string_dtype())),
                       ("array", lambda f: f.create_dataset("metadata", data=np.array([b"{}", b"{}"]))),
                       ("group", lambda f: f.create_group("metadata"))):
        p = tmp_path / f"{name}.h5"
        shutil.copy(good / "good.h5", p)
        with h5py.File(p, "a") as f:
            del f["metadata"]
            make(f)
        refused(p, "metadata dataset is not one fixed-length JSON string")


def test_an_ensembles_large_metadata_is_written_and_read_as_hdf5(tmp_path):
    import copy
    ens = ldaspark.integrate("particle", "gauss-1", n_steps=2, h=0.1, q0=[[1, 0, 0], [2, 0, 0]],
                             v0=[[0, 1, 0], [0, 2, 0]], engine="generic")
    big = copy.copy(ens)
    big.params = {f"p{i}": float(i) for i in range(20000)}    # metadata of ~400 KB (> 64 KiB)
    save_result(big, tmp_path / "e.h5")
    assert load_result(tmp_path / "e.h5").params == big.params


_FLIP_SCRIPT = r"""
import random, sys
sys.path.insert(0, sys.argv[1])
from ldaspark import load_result
from ldaspark.core.errors import LdasparkError
rng = random.Random(7)
for ext in ("h5", "npz"):
    raw = bytearray(open(f"{sys.argv[2]}/good.{ext}", "rb").read())
    for i in range(60):
        b = bytearray(raw)
        for _ in range(rng.randint(1, 8)):
            b[rng.randrange(len(b))] = rng.randrange(256)
        p = f"{sys.argv[3]}/x{i}.{ext}"
        open(p, "wb").write(b)
        try:
            load_result(p)
        except LdasparkError as exc:
            assert "\n" not in str(exc)
print("done")
"""


def test_byte_flipped_files_are_one_error_and_never_hang(good, tmp_path):
    """Random byte flips of a written .h5 and .npz: a Result or one InputError, never another
    exception, a crash or a hang (a subprocess: a loop inside the HDF5 library cannot be
    interrupted)."""
    p = subprocess.run([sys.executable, "-c", _FLIP_SCRIPT, ROOT, str(good), str(tmp_path)],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0 and p.stdout.strip() == "done", (p.stdout[-500:], p.stderr[-2000:])


def test_legacy_h5_metadata_is_read_by_a_child_with_a_time_bound(res, good, tmp_path, monkeypatch):
    """The earlier format's variable-length attribute (which a corrupt heap entry makes the HDF5
    library read forever) is read by a child process; past the time bound it is an InputError,
    not a hang. Control: with the normal bound the same file loads."""
    import shutil
    from ldaspark.core import h5legacy
    legacy = tmp_path / "legacy.h5"
    shutil.copy(good / "good.h5", legacy)
    with h5py.File(legacy, "a") as f:
        del f["metadata"]
    assert np.array_equal(load_result(legacy).q, res.q)
    monkeypatch.setattr(h5legacy, "TIMEOUT", 1e-3)     # the child cannot even start in 1 ms
    with pytest.raises(InputError, match="was not read within"):
        load_result(legacy)


def test_the_legacy_reader_child_never_imports_from_the_working_directory(res, good, tmp_path, monkeypatch):
    """``python -m`` / ``-c`` put the working directory first on the child's sys.path: loading a
    legacy .h5 from a directory holding a planted h5py.py, ctypes.py or ldaspark/ ran them in the
    child (the parent, a console script, never looks there). The child imports what the parent
    did; the file loads and no planted module runs."""
    import shutil
    legacy = tmp_path / "legacy.h5"
    shutil.copy(good / "good.h5", legacy)
    with h5py.File(legacy, "a") as f:
        del f["metadata"]
    markers = []
    for mod in ("h5py", "ctypes", "numpy", "ldaspark/__init__"):
        marker = tmp_path / f"ran-{mod.replace('/', '-')}"
        markers.append(marker)
        (tmp_path / mod).parent.mkdir(exist_ok=True)
        (tmp_path / f"{mod}.py").write_text(f"open({str(marker)!r}, 'w').close()\nraise SystemExit(3)\n")
    monkeypatch.chdir(tmp_path)
    got = load_result("legacy.h5")
    assert [m.name for m in markers if m.exists()] == []
    assert np.array_equal(got.q, res.q)
