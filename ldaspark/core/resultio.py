"""Result files: ``save_result(result, path)`` and ``load_result(path)``, format by extension.

* ``.json`` (and any name without one of the other extensions): the ``ldaspark integrate`` contract (keys scene, method, h, dps, t, q, v, energy,
  constraint, psi, stats; numbers as floats, or as strings of ``dps`` digits after an mpmath
  run), plus engine, status, message, save_every, params, version.
* ``.npz``: named arrays t, q, v, energy, constraint (and psi when the engine forms it) and
  the metadata as a JSON string in the array ``metadata``; no pickled objects.
* ``.h5`` / ``.hdf5``: the same arrays as HDF5 datasets, metadata as attributes of the root
  group (needs h5py: ``pip install ldaspark[h5]``).

mpmath results are stored as decimal strings (full precision) in every format and read back as
mpf at the stored ``dps``. Every file is written atomically (``ldaspark.core.io``).

Also kept (float64, as computed): ``stats`` (JSON key / metadata), the events (``t_events_e``,
``q_events_e``, ``v_events_e`` for event function e) and the dense output's data (``dense_t``,
``dense_q`` with ``dense_c``, ``dense_V`` for the collocation extension or ``dense_v`` for the
Hermite one): arrays in .npz and .h5, in .json under ``extra_arrays`` as {name: {shape, data}}.
"""
from __future__ import annotations

import io
import json
import os
from typing import Any, Union

import numpy as np

from .errors import InputError
from .io import atomic_write_bytes, atomic_write_json
from .result import Result

ARRAYS = ("t", "q", "v", "energy", "constraint", "psi")
META = ("scene", "method", "system", "engine", "h", "dps", "status", "message", "save_every", "params", "version",
        "nfev", "njev", "nlu", "newton_iterations")
FORMATS = (".json", ".npz", ".h5", ".hdf5")


def _ext(path) -> str:
    """The format of ``path``: .npz, .h5 / .hdf5, else .json (any other name, as the
    ``ldaspark integrate --out`` contract has always written JSON)."""
    ext = os.path.splitext(os.fspath(path))[1].lower()
    return ext if ext in FORMATS else ".json"


def _json_value(x: Any) -> Any:
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.floating,)):
        return float(x)
    if isinstance(x, dict):
        return {str(k): _json_value(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_value(v) for v in x]
    if isinstance(x, (str, int, float, bool)) or x is None:
        return x
    return str(x)


def metadata(result: Result) -> dict:
    from .. import __version__
    md = {k: getattr(result, k, None) for k in META if k != "version"}
    md["version"] = __version__
    if result.members is not None:
        md["status"] = [int(s) for s in np.asarray(result.status)]
    return _json_value(md)


def _numbers(a, dps):
    """float64 array, or an array of decimal strings for an mpmath result."""
    a = np.asarray(a)
    if dps is None or a.dtype != object:
        return a.astype(float)
    import mpmath
    with mpmath.workdps(dps):
        return np.vectorize(lambda x: mpmath.nstr(x, dps, strip_zeros=False), otypes=[str])(a) if a.size \
            else a.astype(str)


def _to_json(result: Result) -> dict:
    out = metadata(result)
    for name in ARRAYS:
        a = getattr(result, name)
        out[name] = [] if a is None else _numbers(a, result.dps).tolist()
    out["stats"] = _json_value(result.stats)
    out["extra_arrays"] = {k: {"shape": list(a.shape), "data": a.reshape(-1).tolist()}
                           for k, a in _extra_arrays(result).items()}
    return out


def _extra_arrays(result: Result) -> dict:
    """Events and dense-output data as named float64 arrays (none for an ensemble)."""
    from .dense import CollocationDense, HermiteDense
    out = {}
    if result.members is not None:
        return out
    for e, (te, qe, ve) in enumerate(zip(result.t_events, result.q_events, result.v_events)):
        out[f"t_events_{e}"], out[f"q_events_{e}"], out[f"v_events_{e}"] = (np.asarray(x, float) for x in (te, qe, ve))
    sol = result.sol
    if isinstance(sol, CollocationDense):
        out.update(dense_t=sol.t, dense_q=sol.q, dense_c=sol.c, dense_V=sol.V)
    elif isinstance(sol, HermiteDense):
        out.update(dense_t=sol.t, dense_q=sol.q, dense_v=sol.v)
    return out


def _is_extra(name: str) -> bool:
    return name.startswith(("t_events_", "q_events_", "v_events_", "dense_"))


def _restore_extras(res: Result, extra: dict) -> None:
    """Events and dense output from the arrays of ``_extra_arrays``."""
    from .dense import CollocationDense, HermiteDense
    ne = 0
    while f"t_events_{ne}" in extra:
        ne += 1
    grab = lambda k: np.asarray(extra[k], float)
    res.t_events = [grab(f"t_events_{e}") for e in range(ne)]
    res.q_events = [grab(f"q_events_{e}") for e in range(ne)]
    res.v_events = [grab(f"v_events_{e}") for e in range(ne)]
    if "dense_c" in extra:
        res.sol = CollocationDense(grab("dense_t"), grab("dense_q"), grab("dense_c"), grab("dense_V"))
    elif "dense_v" in extra:
        res.sol = HermiteDense(grab("dense_t"), grab("dense_q"), grab("dense_v"))


def save_result(result: Result, path: Union[str, os.PathLike]) -> None:
    """Write ``result`` to ``path`` (format by extension; atomically)."""
    if result.members is not None and _ext(path) == ".json":
        raise InputError("ensemble results are written as .npz or .h5")
    ext = _ext(path)
    if ext == ".json":
        atomic_write_json(path, _to_json(result))
        return
    arrays = {name: _numbers(getattr(result, name), result.dps) for name in ARRAYS
              if getattr(result, name) is not None}
    arrays.update(_extra_arrays(result))
    md = json.dumps(dict(metadata(result), stats=_json_value(result.stats)))
    if ext == ".npz":
        buf = io.BytesIO()
        np.savez(buf, metadata=np.array(md), **arrays)
        atomic_write_bytes(path, buf.getvalue())
        return
    h5py = _h5py()
    buf = io.BytesIO()
    with h5py.File(buf, "w") as f:
        for name, a in arrays.items():
            f.create_dataset(name, data=a.astype("S") if a.dtype.kind == "U" else a)
        f.attrs["metadata"] = md
        for k in ("scene", "method", "h", "dps", "version", "status"):
            v = json.loads(md)[k]
            f.attrs[k] = json.dumps(v) if not isinstance(v, (str, int, float)) else v
    atomic_write_bytes(path, buf.getvalue())


def _h5py():
    try:
        import h5py
    except ImportError:
        raise InputError("writing or reading .h5 needs h5py (pip install 'ldaspark[h5]')") from None
    return h5py


def _from_numbers(a, dps):
    a = np.asarray(a)
    if a.dtype.kind in "SUO":
        a = a.astype(str)
        if dps is None:
            return a.astype(float)
        import mpmath
        with mpmath.workdps(dps):
            return np.vectorize(mpmath.mpf, otypes=[object])(a) if a.size else a.astype(object)
    return a.astype(float)


def _build(md: dict, arrays: dict) -> Result:
    dps = md.get("dps")
    got = {k: _from_numbers(arrays[k], dps) for k in ARRAYS if k in arrays}
    missing = [k for k in ARRAYS[:5] if k not in got]
    if missing:
        raise InputError(f"result file lacks {', '.join(missing)}")
    psi = got.get("psi")
    if psi is not None and psi.size == 0:
        psi = None
    n = got["q"].shape[-1] if got["q"].ndim > 1 else 0
    t = got["t"]
    m = np.asarray(got["constraint"]).shape[-1] if np.asarray(got["constraint"]).ndim > 1 else 0
    kw = {k: md[k] for k in ("scene", "method", "system", "engine", "h", "dps", "message", "save_every", "params",
                              "nfev", "njev", "nlu", "newton_iterations") if md.get(k) is not None}
    status = md.get("status", 0)
    res = Result(t, got["q"].reshape(len(t), n) if t.ndim == 1 else got["q"], got["v"].reshape(got["q"].shape),
                 got["energy"], got["constraint"].reshape(len(t), m) if t.ndim == 1 else got["constraint"], psi,
                 np.asarray(status) if isinstance(status, list) else int(status), **kw)
    res.stats = md.get("stats", {}) or {}
    return res


def load_result(path: Union[str, os.PathLike]) -> Result:
    """Read a result file written by ``save_result`` or ``ldaspark integrate --out`` (any format)."""
    ext = _ext(path)
    if not os.path.exists(path):
        raise InputError(f"no such result file: {os.fspath(path)}")
    try:
        if ext == ".json":
            with open(path, encoding="utf-8") as f:
                d = json.load(f)
            if not isinstance(d, dict):
                raise InputError(f"{os.fspath(path)}: not a result file")
            arrays = {k: np.array(d[k], dtype=object if d.get("dps") else float) for k in ARRAYS if k in d}
            if "psi" in arrays and d.get("dps"):
                arrays["psi"] = np.array(d["psi"], dtype=str) if d["psi"] else np.zeros(0)
            for k in ARRAYS:
                if k in arrays and d.get("dps"):
                    arrays[k] = np.asarray(arrays[k]).astype(str)
            res = _build(d, arrays)
            _restore_extras(res, {k: np.asarray(x["data"], float).reshape(x["shape"])
                                  for k, x in (d.get("extra_arrays") or {}).items()})
            return res
        if ext == ".npz":
            with np.load(path, allow_pickle=False) as z:
                md = json.loads(str(z["metadata"]))
                res = _build(md, {k: z[k] for k in ARRAYS if k in z.files})
                _restore_extras(res, {k: z[k] for k in z.files if _is_extra(k)})
                return res
        h5py = _h5py()
        with h5py.File(path, "r") as f:
            md = json.loads(f.attrs["metadata"])
            res = _build(md, {k: f[k][()] for k in ARRAYS if k in f})
            _restore_extras(res, {k: f[k][()] for k in f.keys() if _is_extra(k)})
            return res
    except InputError:
        raise
    except (OSError, ValueError, KeyError, json.JSONDecodeError) as exc:
        raise InputError(f"cannot read result file {os.fspath(path)}: {exc}") from None
