"""Bounds, non-finite values, file types and sizes of result files: ``load_result`` checks the file type with
os.stat before opening (a FIFO never blocks, /dev/zero behind a link is never read), bounds
sizes and array headers before reading, refuses NaN, infinity, 1e999, complex and compound
arrays, wrong shapes, metadata that is not a dict or has dps outside [DPS_MIN, DPS_MAX]; the
.npz and .h5 writers refuse NaN as the .json one does. Each attack is also a time bound."""
import io
import json
import os
import shutil
import zipfile

import numpy as np
import pytest

import ldaspark
from ldaspark import load_result, save_result
from ldaspark.core.errors import InputError

from run_helpers import time_bound

h5py = pytest.importorskip("h5py")
FORMATS = ("json", "npz", "h5")


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    d = tmp_path_factory.mktemp("results")
    res = ldaspark.integrate("skate", "gauss-2", t_span=(0, 0.2), h=0.05)
    for ext in FORMATS:
        save_result(res, d / f"good.{ext}")
    mp = ldaspark.integrate("skate", "gauss-2", t_span=(0, 0.1), h="0.05", dps=20)
    save_result(mp, d / "mp.json")
    return d, res


def refused(path, match):
    with time_bound(60), pytest.raises(InputError, match=match):
        load_result(path)


def test_good_files_load(good):
    d, res = good
    for ext in FORMATS:
        back = load_result(d / f"good.{ext}")
        np.testing.assert_array_equal(back.q, res.q)
    assert load_result(d / "mp.json").dps == 20


@pytest.mark.parametrize("token", ["NaN", "-Infinity", "Infinity", "1e999"])
def test_json_nonfinite_numbers_are_refused(good, tmp_path, token):
    text = (good[0] / "good.json").read_text().replace("0.05", token, 1)
    p = tmp_path / "bad.json"
    p.write_text(text)
    refused(p, "not a finite")


@pytest.mark.parametrize("change, match", [
    (dict(dps=100000000), "dps must be between"), (dict(dps=-5), "dps must be between"),
    (dict(dps="30"), "dps"), (dict(status="ok"), "status"), (dict(status=-5), "status"), (dict(status=2), "status"),
    (dict(save_every=0), "save_every"),
    (dict(q="abc"), "q"), (dict(t=[[0.0, 0.05]]), "t has shape"), (dict(energy=[1.0]), "energy has shape"),
    (dict(q=[[1e308 * 10]]), "."),
])
def test_json_bad_content(good, tmp_path, change, match):
    d = json.loads((good[0] / "good.json").read_text())
    if change.get("t") is not None:
        change = dict(change, t=[d["t"]])
    d.update(change)
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(d).replace("Infinity", "1e999"))
    refused(p, match)


def test_json_structure_attacks(tmp_path):
    for name, text, match in (("nested", "[" * 100000 + "]" * 100000, "nested too deeply|not a result"),
                              ("list", "[1, 2, 3]", "not a result file"), ("utf", b"\xff\xfe", "cannot read"),
                              ("mp", json.dumps({"dps": 20, "t": ["1" * 3000], "q": [], "v": [], "energy": [],
                                                 "constraint": []}), "longer than")):
        p = tmp_path / f"{name}.json"
        (p.write_bytes if isinstance(text, bytes) else p.write_text)(text)
        refused(p, match)


def test_special_files_are_refused_without_blocking(tmp_path):
    fifo = tmp_path / "r.json"
    os.mkfifo(fifo)
    refused(fifo, "not a regular file")                 # before: blocked forever in open()
    link = tmp_path / "z.npz"
    os.symlink("/dev/zero", link)
    refused(link, "not a regular file")                 # before: read until MemoryError
    refused("/dev/zero", "not a regular file")
    refused(tmp_path, "not a regular file")
    refused(tmp_path / "missing.json", "no such result file")


def _npz(good, tmp_path, name, **replace):
    z = dict(np.load(good[0] / "good.npz"))
    z.update(replace)
    p = tmp_path / f"{name}.npz"
    np.savez(p, **z)
    return p, z


@pytest.mark.parametrize("name, make, match", [
    ("nan", lambda z: dict(q=np.full_like(z["q"], np.nan)), "NaN"),
    ("complex", lambda z: dict(q=z["q"] + 1j), "complex"),
    ("t2d", lambda z: dict(t=z["t"][None]), "t has shape"),
    ("mdlist", lambda z: dict(metadata=np.array(json.dumps([1, 2]))), "metadata is a list"),
    ("dps", lambda z: dict(metadata=np.array(json.dumps(dict(json.loads(str(z["metadata"])), dps=-5)))), "dps"),
    ("compound", lambda z: dict(q=np.zeros(5, dtype=[("a", "f8"), ("b", "i4")])), "compound"),
    ("bool", lambda z: dict(q=np.ones_like(z["q"], dtype=bool)), "dtype bool"),
])
def test_npz_bad_content(good, tmp_path, name, make, match):
    z = dict(np.load(good[0] / "good.npz"))
    p, _ = _npz(good, tmp_path, name, **make(z))
    refused(p, match)


def test_npz_truncated_and_lying_headers(good, tmp_path):
    raw = (good[0] / "good.npz").read_bytes()
    for cut in (len(raw) // 2, len(raw) - 10, 30):
        p = tmp_path / f"trunc{cut}.npz"
        p.write_bytes(raw[:cut])
        refused(p, "cannot read")
    z = dict(np.load(good[0] / "good.npz"))

    def write(name, q_bytes, compression=zipfile.ZIP_STORED):
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w", compression=compression) as zf:
            for k in z:
                if k == "q":
                    zf.writestr("q.npy", q_bytes)
                else:
                    b = io.BytesIO()
                    np.save(b, z[k])
                    zf.writestr(k + ".npy", b.getvalue())
        p = tmp_path / name
        p.write_bytes(buf.getvalue())
        return p
    h = io.BytesIO()
    np.lib.format.write_array_header_1_0(h, {"descr": "<f8", "fortran_order": False, "shape": (10 ** 15, 3)})
    refused(write("huge.npz", h.getvalue() + b"\0" * 64), "claims 3e\\+15 elements")
    b = io.BytesIO()
    np.save(b, np.zeros((10 ** 7, 3)))                  # 240 MB of zeros deflate to ~0.2 MB
    bomb = write("bomb.npz", b.getvalue(), zipfile.ZIP_DEFLATED)
    assert bomb.stat().st_size < 2 ** 20
    refused(bomb, "refusing to inflate")
    b = io.BytesIO()
    np.save(b, z["q"])
    assert load_result(write("control.npz", b.getvalue(), zipfile.ZIP_DEFLATED)).q.shape == z["q"].shape


@pytest.mark.parametrize("name, make, match", [
    ("group", lambda f: f.create_group("q"), "Group"),
    ("scalar", lambda f: f.create_dataset("q", data=1.0), "scalar"),
    ("compound", lambda f: f.create_dataset("q", data=np.zeros(3, dtype=[("a", "f8"), ("b", "i4")])), "dtype"),
    ("nan", lambda f: f.create_dataset("q", data=np.full((5, 3), np.nan)), "NaN"),
    ("complex", lambda f: f.create_dataset("q", data=np.zeros((5, 3)) + 1j), "dtype complex"),
    ("fill", lambda f: f.create_dataset("q", shape=(10 ** 9, 3), dtype="f8", chunks=(1000, 3)), "claims"),
])
def test_h5_bad_content(good, tmp_path, name, make, match):
    p = tmp_path / f"{name}.h5"
    shutil.copy(good[0] / "good.h5", p)
    with h5py.File(p, "a") as f:
        del f["q"]
        make(f)
    refused(p, match)


@pytest.mark.parametrize("ext", FORMATS)
def test_writers_refuse_nonfinite_results(good, tmp_path, ext):
    res = ldaspark.integrate("skate", "gauss-2", t_span=(0, 0.2), h=0.05)
    save_result(res, tmp_path / f"ok.{ext}")            # control
    res.q = res.q.copy()
    res.q[2, 0] = np.nan
    with pytest.raises(InputError, match="refusing to write"):
        save_result(res, tmp_path / f"bad.{ext}")
    assert not (tmp_path / f"bad.{ext}").exists()
