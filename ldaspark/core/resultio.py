"""Result files: ``save_result(result, path)`` and ``load_result(path)``, format by extension.

* ``.json`` (and any name without one of the other extensions): the ``ldaspark integrate`` contract (keys scene, method, h, dps, t, q, v, energy,
  constraint, psi, stats; numbers as floats, or as strings of ``dps`` digits after an mpmath
  run), plus engine, status, message, save_every, params, version, coordinate_names, and
  ``psi_shape`` when psi is formed but empty (a run that failed at its first step: ``psi`` is
  then ``[]``, as for a kernel without psi, and reads back as None without it).
* ``.npz``: named arrays t, q, v, energy, constraint (and psi when the engine forms it) and
  the metadata as a JSON string in the array ``metadata``; no pickled objects.
* ``.h5`` / ``.hdf5``: the same arrays as HDF5 datasets, the metadata as the scalar dataset
  ``metadata`` (one fixed-length JSON string) and, for other tools, as attributes of the root
  group (needs h5py: ``pip install ldaspark[h5]``).

mpmath results are stored as decimal strings (full precision) in every format and read back as
mpf at the stored ``dps``. Every file is written atomically (``ldaspark.core.io``).

Reader policy, one for every format (docs/reliability.md, "Trust model for checkpoints and result
files"): what ``save_result`` writes, ``load_result`` reads, and nothing else. A result file never
reaches outside itself: in HDF5 only hard-linked groups and datasets are accepted (external and
soft links, external raw storage, virtual datasets, committed datatypes and unknown filters are
refused before any data is read, so a FIFO or device they name is never opened); every array
has a whitelisted dtype (integer, float, or non-empty byte / unicode strings for the decimal
strings of an mpmath run) with a non-zero item size, and its element count, from the header, is
bounded by the bytes the file holds before anything is allocated; object arrays are never
loaded. Non-finite numbers are refused at write time in every format (arrays, events, dense
output, metadata and ``stats``: a file that one format's reader would refuse is never written),
and at read time.

``coordinate_names`` (the names of q's columns) is in the metadata of every format; a file
without it (earlier versions) reads as None; a value other than n non-empty printable strings of
at most MAX_NAME_CHARS characters is refused, on reading and before writing.

Also kept (float64, as computed): ``stats`` (JSON key / metadata), the events (``t_events_e``,
``q_events_e``, ``v_events_e`` for event function e) and the dense output's data (``dense_t``,
``dense_q``, ``dense_v`` with ``dense_c``, ``dense_V`` for the stage polynomial corrected to the
grid, ``dense_q``, ``dense_v`` alone for the cubic Hermite one; a file without ``dense_v`` next to
``dense_c`` (written before the correction) reads as the uncorrected stage polynomial it was
saved with): arrays in .npz and .h5, in .json under ``extra_arrays`` as {name: {shape, data}}.
An ensemble (.npz and .h5 only) keeps ``n_valid`` in its metadata and each member's events and
dense output under the prefix ``member<j>_``; it reads back with its members (their valid rows,
status, message, counters, stats and params) and the batch's events and dense output made of
theirs, as ``core.result.stack`` makes them.
"""
from __future__ import annotations

import io
import json
import math
import os
from typing import Any, Union

import numpy as np

from .errors import InputError
from .validate import _describe
from .io import atomic_write_bytes, atomic_write_json, check_destination
from .result import STATUS_EVENT, STATUS_GUARD, Result

ARRAYS = ("t", "q", "v", "energy", "constraint", "psi")
META = ("scene", "method", "system", "engine", "h", "dps", "status", "message", "save_every", "params", "version",
        "nfev", "njev", "nlu", "newton_iterations", "coordinate_names", "n_valid")
#: longest coordinate name read or written (printed sympy symbols are a few characters)
MAX_NAME_CHARS = 256
FORMATS = (".json", ".npz", ".h5", ".hdf5")


def _ext(path) -> str:
    """The format of ``path``: .npz, .h5 / .hdf5, else .json (any other name, as the
    ``ldaspark integrate --out`` contract has always written JSON)."""
    ext = os.path.splitext(os.fspath(path))[1].lower()
    return ext if ext in FORMATS else ".json"


def _json_value(x: Any) -> Any:
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.floating,)):
        return float(x)
    if isinstance(x, dict):
        return {str(k): _json_value(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_value(v) for v in x]
    if isinstance(x, np.ndarray) and x.dtype.kind in "biuf":
        # an ensemble's counters; a 0-d array (h = np.array(0.1), which integrate takes and
        # keeps in Result.h) is its number: tolist() gives the number, nested lists otherwise
        return _json_value(x.tolist())
    if isinstance(x, (str, int, float, bool)) or x is None:
        return x
    return str(x)


def _mp_digits(x: Any, dps) -> Any:
    """``x`` (h; params: a dict, an ensemble's {"members": [...]}) with every mpmath number as the
    decimal string of ``dps`` significant digits that the arrays are stored with (17 for a float64
    run): ``str(mpf)`` prints at mpmath's global precision, 15 digits."""
    import mpmath
    if isinstance(x, dict):
        return {k: _mp_digits(v, dps) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_mp_digits(v, dps) for v in x]
    if isinstance(x, mpmath.mpf):
        digits = dps if isinstance(dps, int) and not isinstance(dps, bool) and dps > 0 else 17
        with mpmath.workdps(max(digits, mpmath.mp.dps)):
            return mpmath.nstr(x, digits, strip_zeros=False)
    return x


def metadata(result: Result) -> dict:
    from .._version import __version__
    md = {k: getattr(result, k, None) for k in META if k != "version"}
    md["params"], md["h"] = _mp_digits(md["params"], result.dps), _mp_digits(md["h"], result.dps)
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
    if result.psi is not None and np.size(result.psi) == 0 and np.ndim(result.psi) > 1:
        # an empty psi (a run that failed at its first step) is "[]" in JSON, which is also what
        # a kernel without psi writes: its shape says it was formed (.npz and .h5 keep it)
        out["psi_shape"] = [int(e) for e in np.shape(result.psi)]
    out["stats"] = _json_value(result.stats)
    out["extra_arrays"] = {k: {"shape": list(a.shape), "data": a.reshape(-1).tolist()}
                           for k, a in _extra_arrays(result).items()}
    return out


def _extra_arrays(result: Result) -> dict:
    """Events and dense-output data as named float64 arrays; an ensemble's are its members',
    member j's under the prefix ``member<j>_`` (the batch's events and dense output are made of
    them: ``core.result.batch_events_and_dense``)."""
    from .dense import CollocationDense, HermiteDense
    out = {}
    if result.members is not None:
        for j, member in enumerate(result.members):
            out.update({f"member{j}_{k}": a for k, a in _extra_arrays(member).items()})
        return out
    for e, (te, qe, ve) in enumerate(zip(result.t_events, result.q_events, result.v_events)):
        out[f"t_events_{e}"], out[f"q_events_{e}"], out[f"v_events_{e}"] = (np.asarray(x, float) for x in (te, qe, ve))
    sol = result.sol
    if isinstance(sol, CollocationDense):
        out.update(dense_t=sol.t, dense_q=sol.q, dense_c=sol.c, dense_V=sol.V)
        if sol.v is not None:            # the grid velocities of the correction (absent in old files)
            out.update(dense_v=sol.v)
    elif isinstance(sol, HermiteDense):
        out.update(dense_t=sol.t, dense_q=sol.q, dense_v=sol.v)
    return out


def _is_extra(name: str) -> bool:
    return name.startswith(("t_events_", "q_events_", "v_events_", "dense_", "member"))


def _json_extras(ex) -> dict:
    """The ``extra_arrays`` of a .json file, {name: {shape, data}}, as arrays: checked like
    every other field (a dict of names, shapes of non-negative integers matching the data's
    length, numbers), never an AttributeError or a reshape error."""
    if ex is None:
        return {}
    if not isinstance(ex, dict):
        raise InputError(f"extra_arrays must be a dict of arrays, got {type(ex).__name__}")
    out = {}
    for k, x in ex.items():
        if not isinstance(x, dict) or set(x) != {"shape", "data"}:
            raise InputError(f"extra_arrays[{str(k)[:40]!r}] must be {{shape, data}}")
        shape, data = x["shape"], x["data"]
        if not isinstance(shape, list) or len(shape) > 4 or not all(
                isinstance(e, int) and not isinstance(e, bool) and 0 <= e <= 2 ** 31 for e in shape):
            raise InputError(f"extra_arrays[{str(k)[:40]!r}]: shape must be a list of non-negative integers")
        if not isinstance(data, list) or len(data) != math.prod(shape):
            raise InputError(f"extra_arrays[{str(k)[:40]!r}]: data must be a flat list of {math.prod(shape)} numbers")
        if not all(isinstance(e, (int, float)) and not isinstance(e, bool) for e in data):
            raise InputError(f"extra_arrays[{str(k)[:40]!r}]: data must hold numbers only")
        try:
            out[k] = np.asarray(data, float).reshape(shape)
        except OverflowError:
            raise InputError(f"extra_arrays[{str(k)[:40]!r}]: a number beyond float64") from None
    return out


def _restore_extras(res: Result, extra: dict) -> None:
    """Events and dense output from the arrays of ``_extra_arrays``."""
    from .dense import CollocationDense, HermiteDense
    ne = 0
    while f"t_events_{ne}" in extra:
        ne += 1
    res.t_events, res.q_events, res.v_events = [], [], []
    def grab(k):
        a = np.asarray(extra[k], float)
        if not np.all(np.isfinite(a)):
            raise InputError(f"{k} contains NaN or infinity")
        return a
    def need(k, shape, what):
        if k not in extra:
            raise InputError(f"{k} is missing ({what})")
        a = grab(k)
        if a.ndim != len(shape) or any(want is not None and got != want for got, want in zip(a.shape, shape)):
            raise InputError(f"{k} has shape {a.shape}, not {tuple('*' if w is None else w for w in shape)} ({what})")
        return a
    n = res.q.shape[-1]
    if res.members is None and np.asarray(res.t).ndim == 1:
        for e in range(ne):
            te = need(f"t_events_{e}", (None,), "event times")
            res.t_events.append(te)
            res.q_events.append(need(f"q_events_{e}", (len(te), n), "event positions"))
            res.v_events.append(need(f"v_events_{e}", (len(te), n), "event velocities"))
        if "dense_c" in extra or "dense_v" in extra:
            t = need("dense_t", (None,), "dense output nodes")
            if len(t) < 2 or not (np.all(np.diff(t) > 0) or np.all(np.diff(t) < 0)):
                raise InputError("dense_t is not a strictly monotone sequence of at least two times")
            q = need("dense_q", (len(t), n), "dense output")
            if "dense_c" in extra:
                c = need("dense_c", (None,), "collocation nodes")
                if not len(c):
                    raise InputError("dense_c is empty")
                # dense_v: the grid velocities of the corrected stage polynomial; a file written
                # before the correction has none and keeps the polynomial it was saved with
                vg = need("dense_v", (len(t), n), "grid velocities") if "dense_v" in extra else None
                res.sol = CollocationDense(t, q, c, need("dense_V", (len(t) - 1, len(c), n), "stage velocities"), vg)
            else:
                res.sol = HermiteDense(t, q, need("dense_v", (len(t), n), "dense output"))
    elif res.members is not None:       # an ensemble with its members (``_restore_members``)
        from .result import batch_events_and_dense
        used = 0
        for j, member in enumerate(res.members):
            pre = f"member{j}_"
            sub = {k[len(pre):]: a for k, a in extra.items() if k.startswith(pre)}
            used += len(sub)
            _restore_extras(member, sub)
        if used != len(extra):
            raise InputError(f"{sorted(set(extra))[0][:40]}: not the events or dense output of a member")
        events, res.sol = batch_events_and_dense(res.members)
        res.t_events, res.q_events, res.v_events = events["t_events"], events["q_events"], events["v_events"]
    elif extra:
        raise InputError("events or dense output stored with an ensemble without its members")


def _check_finite_arrays(result: Result) -> None:
    """Every format refuses NaN, infinity and complex numbers, as the JSON writer always did: a
    file that ``load_result`` would refuse is never written."""
    import mpmath
    for name in ARRAYS:
        a = getattr(result, name)
        if a is None:
            continue
        a = np.asarray(a)
        if a.dtype == object:
            ok = all(isinstance(x, (mpmath.mpf, int, float, np.integer, np.floating)) and mpmath.isfinite(x)
                     for x in a.reshape(-1))
        else:
            ok = a.dtype.kind in "iuf" and bool(np.all(np.isfinite(a)))
        if not ok:
            raise InputError(f"refusing to write a result whose {name} contains NaN, infinity or non-real values")


def _check_finite_json(x, where: str) -> None:
    """Every number in the JSON value ``x`` (metadata, stats) is finite: the .json writer would
    refuse the rest, and the readers of every format do."""
    if isinstance(x, float) and not np.isfinite(x):
        raise InputError(f"refusing to write a result whose {where} is {x} (not finite: no format would read "
                         "it back)")
    if isinstance(x, dict):
        for k, v in x.items():
            _check_finite_json(v, f"{where}[{k!r}]")
    elif isinstance(x, list):
        for i, v in enumerate(x):
            _check_finite_json(v, f"{where}[{i}]")


def _check_writable(result: Result) -> dict:
    """The checks every writer makes before touching the file, after ``_check_finite_arrays``;
    returns the extra arrays."""
    extra = _extra_arrays(result)
    for k, a in extra.items():
        a = np.asarray(a)
        if a.dtype.kind not in "iuf" or not np.all(np.isfinite(a)):
            raise InputError(f"refusing to write a result whose {k} contains NaN, infinity or non-real values")
    # the reader's structural checks of events and dense output, on what is about to be written
    import types
    def shell(r, members=None):    # what _restore_extras reads and sets, apart from ``r``
        return types.SimpleNamespace(q=np.asarray(r.q), t=r.t, members=members, sol=None)
    probe = shell(result, None if result.members is None else [shell(m) for m in result.members])
    try:
        _restore_extras(probe, extra)
    except InputError as exc:
        raise InputError(f"refusing to write a result that the reader would refuse: {exc}") from None
    md = metadata(result)
    for k, v in md.items():
        _check_finite_json(v, k)
    try:
        _check_names(md.get("coordinate_names"), np.shape(result.q)[-1])
    except InputError as exc:
        raise InputError(f"refusing to write a result that the reader would refuse: {exc}") from None
    _check_finite_json(_json_value(result.stats), "stats")
    return extra


def check_path(path, what: str = "result file") -> str:
    """``path`` as a str: a str or os.PathLike naming a file (not bytes, not an int file
    descriptor, not empty, no NUL character); InputError otherwise."""
    if isinstance(path, (bool, int)):
        raise InputError(f"the {what} must be a path (str or os.PathLike), got the integer {path!r} "
                         "(file descriptors are not accepted)")
    if not isinstance(path, (str, os.PathLike)):
        raise InputError(f"the {what} must be a path (str or os.PathLike), got {type(path).__name__}")
    try:
        p = os.fspath(path)
    except TypeError as exc:
        raise InputError(f"the {what} must be a path: {exc}") from None
    if not isinstance(p, str):
        raise InputError(f"the {what} must be a str path, got {type(p).__name__}")
    if not p:
        raise InputError(f"the {what} path is empty")
    if "\0" in p:
        raise InputError(f"the {what} path contains a NUL character")
    return p


def check_output(path: Union[str, os.PathLike]) -> str:
    """``path`` (a str) if ``save_result`` could write a result there, else the LdasparkError it would
    raise at the end: not a path, a directory, socket or other target that is not a regular file,
    a device or FIFO (``core.io._destination``), an ``.h5`` without h5py. A run checks its output
    with this before it starts, so that it never computes for a file it then refuses."""
    path = check_path(path)
    check_destination(path)
    if _ext(path) in (".h5", ".hdf5"):
        _h5py()
    return path


def save_result(result: Result, path: Union[str, os.PathLike]) -> None:
    """Write a Result to a file, atomically; the format follows the extension.

    Parameters
    ----------
    result : Result
        What `integrate` returned.
    path : str or os.PathLike
        ``.npz``, ``.h5`` / ``.hdf5`` (h5py needed), any other name JSON (the ``ldaspark
        integrate --out`` contract); the file is written to a temporary name beside it and
        renamed, so an existing file is replaced whole or not at all. A character device or a
        FIFO is written directly, as a shell redirection would (a FIFO blocks until a reader
        opens it); a symbolic link's target is replaced, the link kept (``ldaspark.core.io``).

    Returns
    -------
    None

    Raises
    ------
    InputError
        For a ``path`` that is not a str or os.PathLike, an ensemble written as JSON, or values
        no format holds: NaN, infinity and complex values are refused in every format, in the
        arrays, the events, the dense output, the metadata and ``stats`` alike (nothing is
        written).
    LdasparkError
        For a target that cannot be written or must not be replaced (a directory, a socket, a
        block device, a place the process may not write), in one line.

    See Also
    --------
    load_result : read it back.

    Examples
    --------
    >>> import os, tempfile, ldaspark
    >>> res = ldaspark.integrate("particle", "gauss-1", t_span=(0, 1), h=0.5, engine="generic")
    >>> path = os.path.join(tempfile.mkdtemp(), "run.npz")
    >>> ldaspark.save_result(res, path)
    >>> ldaspark.load_result(path).q.shape
    (3, 3)
    """
    if not isinstance(result, Result):
        hint = (" (a run_many ensemble: ldaspark.core.result.from_ensemble(ens, method=..., h=...) makes it one "
                "batched Result, saved as .npz or .h5)" if type(result).__name__ == "EnsembleResult" else "")
        raise InputError(f"save_result needs a Result, got {type(result).__name__}{hint}")
    path = check_path(path)
    if result.members is not None and _ext(path) == ".json":
        raise InputError("ensemble results are written as .npz or .h5")
    _check_finite_arrays(result)
    ext = _ext(path)
    extra = _check_writable(result)
    if ext == ".json":
        atomic_write_json(path, _to_json(result))
        return
    arrays = {name: _numbers(getattr(result, name), result.dps) for name in ARRAYS
              if getattr(result, name) is not None}
    arrays.update(extra)
    try:
        md = json.dumps(dict(metadata(result), stats=_json_value(result.stats)))
    except ValueError as exc:           # an integer of more than 4300 digits (h = 10**5000)
        raise InputError(f"cannot write {path}: the metadata holds a value JSON cannot write "
                         f"({str(exc).splitlines()[0][:80]})") from None
    if ext == ".npz":
        buf = io.BytesIO()
        np.savez(buf, metadata=np.array(md), **arrays)
        atomic_write_bytes(path, buf.getvalue())
        return
    h5py = _h5py()
    if len(arrays) + 1 > MAX_H5_OBJECTS:     # the reader's bound: never write a file it refuses
        raise InputError(f"cannot write {path}: {len(arrays) + 1} datasets (an ensemble's events and dense output, "
                         f"5 a member), more than the {MAX_H5_OBJECTS} an .h5 result file may hold; write .npz")
    buf = io.BytesIO()
    try:
        _write_h5(h5py, buf, arrays, md)
    except (TypeError, ValueError, OverflowError) as exc:       # a value HDF5 has no type for
        raise InputError(f"cannot write {path}: {str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__}") \
            from None
    atomic_write_bytes(path, buf.getvalue())


def _write_h5(h5py, buf, arrays: dict, md: str) -> None:
    with h5py.File(buf, "w") as f:
        for name, a in arrays.items():
            f.create_dataset(name, data=a.astype("S") if a.dtype.kind == "U" else a)
        # what load_result reads: a scalar dataset of one fixed-length string, whose size is known
        # and checked before it is read (a variable-length string lives in the global heap, and a
        # corrupt heap entry makes the HDF5 library loop forever reading it; an attribute of a
        # fixed length is limited to 64 KiB, less than an ensemble's metadata)
        f.create_dataset("metadata", data=np.bytes_(md.encode("utf-8")))
        f.attrs["metadata"] = md                 # the same text for other HDF5 tools (not read here)
        for k in ("scene", "method", "h", "dps", "version", "status"):
            v = json.loads(md)[k]
            # an integer beyond int64 (a 400-digit integer step h) has no HDF5 type: its JSON text
            fits = isinstance(v, (str, float)) or isinstance(v, int) and -2 ** 63 <= v < 2 ** 63
            f.attrs[k] = v if fits else json.dumps(v)


def _h5py():
    try:
        import h5py
    except ImportError:
        raise InputError("writing or reading .h5 needs h5py (pip install 'ldaspark[h5]')") from None
    return h5py


#: longest decimal string read for one number (DPS_MAX digits, sign, point, exponent)
MAX_NUMBER_CHARS = 2100


def _from_numbers(a, dps, name="array"):
    """float64, or mpf at ``dps`` for decimal strings; NaN, infinity and complex refused."""
    a = np.asarray(a)
    if a.dtype.kind in "SUO":
        try:
            a = a.astype(str)
        except (TypeError, ValueError, UnicodeDecodeError):
            raise InputError(f"{name} holds values that are not numbers") from None
        if a.size and max(len(x) for x in a.reshape(-1)) > MAX_NUMBER_CHARS:
            raise InputError(f"{name} holds a number string longer than {MAX_NUMBER_CHARS} characters")
        if dps is None:
            try:
                out = a.astype(float)
            except ValueError:
                raise InputError(f"{name} holds values that are not numbers") from None
        else:
            import mpmath
            with mpmath.workdps(dps):
                try:
                    out = np.vectorize(mpmath.mpf, otypes=[object])(a) if a.size else a.astype(object)
                except (ValueError, TypeError):
                    raise InputError(f"{name} holds values that are not numbers") from None
                if not all(mpmath.isfinite(x) for x in out.reshape(-1)):
                    raise InputError(f"{name} holds NaN or infinity")
            return out
    elif a.dtype.kind not in "iuf":
        raise InputError(f"{name} has dtype {a.dtype} (complex, boolean or compound): not a result array")
    else:
        out = a.astype(float)
    if not np.all(np.isfinite(out)):
        raise InputError(f"{name} holds NaN or infinity")
    return out


def _check_metadata(md) -> dict:
    """The metadata of a result file: a dict whose dps, status and save_every are in range."""
    from .validate import check_dps
    if not isinstance(md, dict):
        raise InputError(f"the metadata is a {type(md).__name__}, not a JSON object")
    try:
        check_dps(md.get("dps"))
    except InputError as exc:
        raise InputError(f"metadata: {exc}") from None
    st = md.get("status", 0)
    # every status a run can end with (``core.result``): STATUS_GUARD (-4) .. STATUS_EVENT (1)
    lo, hi = STATUS_GUARD, STATUS_EVENT
    if not (isinstance(st, int) and not isinstance(st, bool) and lo <= st <= hi) and not (
            isinstance(st, list) and st and all(isinstance(x, int) and not isinstance(x, bool) and lo <= x <= hi
                                                for x in st)):
        raise InputError(f"metadata: status must be an integer in {lo}..{hi} (or a list of them), got {_describe(st)}")
    for key in ("stats", "params"):
        if md.get(key) is not None and not isinstance(md[key], dict):
            raise InputError(f"metadata: {key} must be a JSON object, got {type(md[key]).__name__}")
    for k, v in (md.get("params") or {}).items():
        _refuse_bools(v, f"metadata: params[{str(k)[:40]!r}]")
    for key in ("scene", "method", "system", "engine", "message"):
        if md.get(key) is not None and not isinstance(md[key], (str, list)):
            raise InputError(f"metadata: {key} must be a string, got {type(md[key]).__name__}")
    for key in ("nfev", "njev", "nlu", "newton_iterations"):
        x = md.get(key)
        if x is not None and not (isinstance(x, int) and not isinstance(x, bool) and x >= 0) and not (
                isinstance(x, list) and all(isinstance(y, int) and not isinstance(y, bool) and y >= 0 for y in x)):
            raise InputError(f"metadata: {key} must be a non-negative integer, got {_describe(x)}")
    h = md.get("h")
    if h is not None and (isinstance(h, bool) or not isinstance(h, (int, float, str))):
        raise InputError(f"metadata: h must be a number or a decimal string, got {type(h).__name__}")
    if md.get("version") is not None and not isinstance(md["version"], str):
        raise InputError(f"metadata: version must be a string, got {type(md['version']).__name__}")
    se = md.get("save_every", 1)
    if se is not None and (isinstance(se, bool) or not isinstance(se, int) or se < 1):
        raise InputError(f"metadata: save_every must be a positive integer, got {_describe(se)}")
    _check_names(md.get("coordinate_names"))
    nv = md.get("n_valid")
    if nv is not None and not (isinstance(nv, list) and nv and all(
            isinstance(x, int) and not isinstance(x, bool) and x >= 1 for x in nv)):
        raise InputError(f"metadata: n_valid must be a list of positive integers, got {_describe(nv)}")
    return md


def _check_names(names, n=None) -> None:
    """``coordinate_names`` as read (or about to be written): None (files of earlier versions), or
    a list of non-empty printable strings of at most MAX_NAME_CHARS characters, n of them when the
    number of coordinates n is known. Only compared and printed, never evaluated."""
    if names is None:
        return
    if not isinstance(names, list):
        raise InputError(f"metadata: coordinate_names must be a list of strings, got {type(names).__name__}")
    if n is not None and len(names) != n:
        raise InputError(f"metadata: coordinate_names has {len(names)} names for n = {n} coordinates")
    for i, x in enumerate(names):
        if not isinstance(x, str) or not 0 < len(x) <= MAX_NAME_CHARS or not x.isprintable():
            raise InputError(f"metadata: coordinate_names[{i}] must be a non-empty printable string of at most "
                             f"{MAX_NAME_CHARS} characters, got {str(x)[:40]!r}")


def _check_shapes(got: dict, batch: bool) -> None:
    """t (S,), q and v (S, n), energy (S,), constraint (S, m), psi (S - 1, s, m) or empty; an
    ensemble (status a list) has a leading axis B on each. A 2-D t of a single run is refused."""
    lead = 1 if batch else 0
    t = got["t"]
    if t.ndim != 1 + lead or t.shape[-1] == 0:
        raise InputError(f"t has shape {t.shape}; a {'ensemble' if batch else 'single run'} needs "
                         f"{'(B, S)' if batch else '(S,)'} with S >= 1")
    S = t.shape[-1]
    pre = t.shape[:lead]
    for name, nd in (("q", 2), ("v", 2), ("energy", 1), ("constraint", 2)):
        a = got[name]
        if a.ndim != nd + lead or a.shape[:lead + 1] != pre + (S,):
            raise InputError(f"{name} has shape {a.shape}, not matching t {t.shape}")
    if got["v"].shape != got["q"].shape or got["q"].shape[-1] == 0:
        raise InputError(f"q and v have shapes {got['q'].shape} and {got['v'].shape}")
    psi = got.get("psi")
    if psi is not None and (psi.size or psi.ndim > 1) and (psi.ndim != 3 + lead or psi.shape[lead] != S - 1):
        raise InputError(f"psi has shape {psi.shape}, not matching t {t.shape}")


def _json_empty_psi(d: dict) -> np.ndarray:
    """The empty psi of a .json file with ``psi_shape`` (``_to_json``): a list of 3 or 4
    non-negative integers with a zero among them, and ``psi`` the empty list."""
    shape = d["psi_shape"]
    if not (isinstance(shape, list) and len(shape) in (3, 4) and all(
            isinstance(e, int) and not isinstance(e, bool) and 0 <= e <= 2 ** 31 for e in shape)
            and 0 in shape and d.get("psi") == []):
        raise InputError(f"psi_shape must be the shape of an empty psi (3 or 4 non-negative integers, one of them 0, "
                         f"and psi []), got {_describe(shape)}")
    return np.zeros(shape, dtype=str if d.get("dps") else float)


def _build(md: dict, arrays: dict) -> Result:
    md = _check_metadata(md)
    dps = md.get("dps")
    missing = [k for k in ARRAYS[:5] if k not in arrays]
    if missing:
        raise InputError(f"result file lacks {', '.join(missing)}")
    got = {k: _from_numbers(arrays[k], dps, k) for k in ARRAYS if k in arrays}
    _check_shapes(got, isinstance(md.get("status"), list))
    psi = got.get("psi")
    if psi is not None and psi.size == 0 and psi.ndim != np.ndim(got["t"]) + 2:
        psi = None          # "[]": no psi formed; an empty (S - 1, s, m) psi is kept as it was written
    n = got["q"].shape[-1] if got["q"].ndim > 1 else 0
    t = got["t"]
    m = np.asarray(got["constraint"]).shape[-1] if np.asarray(got["constraint"]).ndim > 1 else 0
    kw = {k: md[k] for k in ("scene", "method", "system", "engine", "h", "dps", "message", "save_every", "params",
                              "nfev", "njev", "nlu", "newton_iterations") if md.get(k) is not None}
    for c in ("nfev", "njev", "nlu", "newton_iterations"):
        if isinstance(kw.get(c), list):                 # an ensemble's counters, as written
            kw[c] = np.asarray(kw[c], dtype=np.int64)
    status = md.get("status", 0)
    res = Result(t, got["q"].reshape(len(t), n) if t.ndim == 1 else got["q"], got["v"].reshape(got["q"].shape),
                 got["energy"], got["constraint"].reshape(len(t), m) if t.ndim == 1 else got["constraint"], psi,
                 np.asarray(status) if isinstance(status, list) else int(status), **kw)
    res.stats = md.get("stats", {}) or {}
    _check_names(md.get("coordinate_names"), n)
    res.coordinate_names = md.get("coordinate_names")
    if isinstance(status, list) and md.get("n_valid") is not None:
        _restore_members(res, md)
    return res


def _restore_members(res: Result, md: dict) -> None:
    """An ensemble's ``n_valid`` and ``members`` (``core.result.stack``) from its file: member j
    is its first n_valid[j] rows (the rest repeat its last state), its status, message, counters,
    stats and params; files of earlier versions (no ``n_valid``) keep ``members`` None."""
    B, S = np.shape(res.t)
    nv = md["n_valid"]
    if len(nv) != B or max(nv) > S:
        raise InputError(f"metadata: n_valid {str(nv)[:40]} does not match {B} members of {S} samples")
    msgs = res.message
    if not (isinstance(msgs, list) and len(msgs) == B and all(isinstance(x, str) for x in msgs)):
        raise InputError(f"metadata: message must be a list of {B} strings for an ensemble")
    counters = {}
    for c in ("nfev", "njev", "nlu", "newton_iterations"):
        a = np.asarray(getattr(res, c))
        if a.shape != (B,):
            raise InputError(f"metadata: {c} must be a list of {B} counts for an ensemble")
        counters[c] = a

    def per_member(d):
        got = d.get("members") if isinstance(d, dict) else None
        return got if isinstance(got, list) and len(got) == B and all(isinstance(x, dict) for x in got) \
            else [{} for _ in range(B)]
    stats, params = per_member(res.stats), per_member(res.params)
    res.n_valid = np.array(nv, dtype=int)
    res.members = [
        Result(res.t[j, :k], res.q[j, :k], res.v[j, :k], res.energy[j, :k], res.constraint[j, :k],
               None if res.psi is None else res.psi[j, :k - 1], int(res.status[j]), msgs[j],
               *(int(counters[c][j]) for c in ("nfev", "njev", "nlu", "newton_iterations")),
               method=res.method, system=res.system, scene=res.scene, engine=res.engine, h=res.h, dps=res.dps,
               save_every=res.save_every, params=params[j], stats=stats[j],
               coordinate_names=None if res.coordinate_names is None else list(res.coordinate_names))
        for j, k in enumerate(nv)]


def _refuse_bools(x, name: str) -> None:
    """JSON ``true`` / ``false`` where a number belongs (the arrays q, t, ...; a parameter value):
    refused, naming the place and what is expected (NumPy would read them as 1.0 and 0.0).
    Iterative, so that a deep list is not a RecursionError."""
    todo = [(x, name)]
    while todo:
        v, where = todo.pop()
        if isinstance(v, bool):
            raise InputError(f"{where} is the JSON boolean {str(v).lower()}, not a number (expected a number "
                             "or a decimal string)")
        if isinstance(v, list):
            todo.extend((e, f"{where}[{i}]") for i, e in enumerate(v))


def _no_constant(name):
    raise InputError(f"{name} is not a finite number")


def _finite_float(text):
    x = float(text)
    if not np.isfinite(x):               # 1e999
        raise InputError(f"{text[:40]} is not a finite float64 number")
    return x


def _dtype_refusal(k: str, dtype, strings: bool) -> str:
    """"" when ``dtype`` is one the writer writes for the array ``k`` (integer or float; for the
    trajectory arrays also non-empty strings: an mpmath run's decimal digits), else why not."""
    if dtype.hasobject:
        return f"{k} is an object array (pickled data are never loaded)"
    if dtype.fields is not None:
        return f"{k} has a compound dtype: not a result array"
    if dtype.kind not in ("iuf" + ("SU" if strings else "")) or dtype.subdtype is not None:
        return f"{k} has dtype {dtype}: not a result array"
    if dtype.itemsize == 0:                  # U0 / S0: 10^12 elements would cost nothing on disk
        return f"{k} has dtype {dtype.str} with zero item size: not a result array"
    return ""


def _npz_arrays(path, z) -> dict:
    """The arrays of an open .npz, each header read (and bounded) before its data: a header
    claiming 1e15 elements, a zero-width dtype, a truncated member or a pickled object array is
    one InputError."""
    out = {}
    names = set(z.files)
    for k in ARRAYS + ("metadata",) + tuple(sorted(n for n in names if _is_extra(n))):
        if k not in names:
            continue
        info = z.zip.getinfo(k + ".npy")
        with z.zip.open(info) as f:
            version = np.lib.format.read_magic(f)
            hdr = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                   else np.lib.format.read_array_header_2_0)(f)
        shape, _, dtype = hdr
        n = int(np.prod(shape, dtype=object)) if shape else 1
        why = _dtype_refusal(k, dtype, k in ARRAYS + ("metadata",))
        if k == "metadata" and not why and (dtype.kind != "U" or shape != ()):
            why = f"metadata is a {dtype} array of shape {shape}, not a JSON string"
        if why:
            raise InputError(why)
        if n * dtype.itemsize > info.file_size:
            raise InputError(f"{k}: the header claims {n:.3g} elements, more than the file holds (truncated?)")
        # a compressed member inflates by at most 64x (trajectories compress 1-3x; 1.4 MB of
        # zeros claiming 2.9 GB is refused before it is inflated)
        if info.file_size > max(64 * info.compress_size, 2 ** 24):
            raise InputError(f"{k}: {info.file_size} bytes compressed into {info.compress_size}: refusing to inflate")
        out[k] = z[k]
    return out


#: objects visited in an HDF5 file (a result has ~20 datasets; hard links can make cycles)
MAX_H5_OBJECTS = 4096
MAX_H5_DEPTH = 16
#: HDF5 filters accepted on a dataset (deflate, shuffle, fletcher32: built into the library);
#: any other would make HDF5 search its plugin path for a shared library to load
H5_FILTERS = (1, 2, 3)


def _h5_check_dataset(name, ds) -> None:
    """Refuse a dataset that reaches outside the file (external raw storage, a virtual dataset)
    or needs a filter plugin, before any of its data is read."""
    dcpl = ds.id.get_create_plist()
    h5d = __import__("h5py").h5d
    if ds.is_virtual or dcpl.get_layout() == h5d.VIRTUAL:
        raise InputError(f"{name} is a virtual dataset (its data live in other files): refused")
    if ds.external or dcpl.get_external_count():
        raise InputError(f"{name} keeps its data in external files: refused")
    for i in range(dcpl.get_nfilters()):
        code = dcpl.get_filter(i)[0]
        if code not in H5_FILTERS:
            raise InputError(f"{name} needs the HDF5 filter {code} (only deflate, shuffle and fletcher32 are read)")


def _h5_check_tree(f) -> None:
    """Every link in the file is a hard link to a group or a dataset that stays inside the file
    (``_h5_check_dataset``): external and soft links, user-defined links and committed datatypes
    are refused, without resolving them (an external link to a FIFO is never opened)."""
    h5py = _h5py()
    seen, todo = 0, [(f, "", 0)]
    while todo:
        group, prefix, depth = todo.pop()
        if depth > MAX_H5_DEPTH:
            raise InputError(f"groups nested more than {MAX_H5_DEPTH} deep at {prefix}")
        for key in group.keys():                      # link names only: nothing is resolved
            name = f"{prefix}/{key}"
            seen += 1
            if seen > MAX_H5_OBJECTS:
                raise InputError(f"more than {MAX_H5_OBJECTS} objects: not a result file")
            link = group.get(key, getlink=True)
            if isinstance(link, h5py.ExternalLink):
                raise InputError(f"{name} is an external link (to {link.filename}): refused")
            if isinstance(link, h5py.SoftLink):
                raise InputError(f"{name} is a soft link (to {link.path}): refused")
            if not isinstance(link, h5py.HardLink):
                raise InputError(f"{name} is a {type(link).__name__}: refused")
            cls = group.get(key, getclass=True)
            if cls is h5py.Dataset:
                _h5_check_dataset(name, group[key])
            elif cls is h5py.Group:
                todo.append((group[key], name, depth + 1))
            else:
                raise InputError(f"{name} is an HDF5 {getattr(cls, '__name__', cls)}, not a group or dataset")


#: longest metadata text read from an HDF5 file (an ensemble of 10^5 members needs ~2 MB)
MAX_H5_METADATA = 64 * 2 ** 20


def _h5_metadata(f, fh) -> str:
    """The metadata text: the scalar dataset ``metadata`` of one fixed-length byte string (what
    ``save_result`` writes), its size checked before it is read; files of earlier versions have
    only the root attribute ``metadata`` (a variable-length string of at most 1 MiB), read by
    ``h5legacy`` in a child process with a time bound (``fh``: the open file)."""
    h5py = _h5py()
    if "metadata" in f:
        ds = f["metadata"]
        if not isinstance(ds, h5py.Dataset) or ds.shape != () or ds.dtype.kind != "S" or \
                not 0 < ds.dtype.itemsize <= MAX_H5_METADATA:
            raise InputError("the metadata dataset is not one fixed-length JSON string")
        raw = ds[()]
    else:
        # the earlier format's variable-length attribute: read in a child process with a time
        # bound, since a corrupt heap entry hangs the HDF5 library inside the read
        from .h5legacy import read_legacy_metadata
        if "metadata" not in f.attrs:
            raise InputError("no metadata attribute")
        raw = read_legacy_metadata(fh)
    if isinstance(raw, (bytes, np.bytes_)):
        raw = bytes(raw).decode("utf-8")
    if not isinstance(raw, str) or len(raw) > MAX_H5_METADATA:
        raise InputError("the metadata is not a JSON string")
    return raw


def _h5_arrays(f) -> dict:
    """The datasets of an open HDF5 file (``_h5_check_tree`` passed): datasets only (no groups),
    not scalars, numeric or string dtype of non-zero item size, bounded size; read after these
    checks."""
    h5py = _h5py()
    out = {}
    for k in ARRAYS + tuple(sorted(n for n in f.keys() if _is_extra(n))):
        if k not in f:
            continue
        ds = f[k]
        if not isinstance(ds, h5py.Dataset):
            raise InputError(f"{k} is an HDF5 {type(ds).__name__}, not a dataset")
        if ds.shape is None or ds.ndim == 0:
            raise InputError(f"{k} is a scalar, not an array")
        if ds.dtype.kind == "U" or h5py.check_string_dtype(ds.dtype) is not None and ds.dtype.kind == "O":
            raise InputError(f"{k} has a variable-length string dtype: not a result array")
        why = _dtype_refusal(k, ds.dtype, k in ARRAYS)
        if why:
            raise InputError(why.replace(" (pickled data are never loaded)", ""))
        need, held = int(ds.size) * ds.dtype.itemsize, int(ds.id.get_storage_size())
        # a chunked, compressed or fill-value dataset may claim far more than the file holds:
        # at most 64x what is stored (or 16 MiB) is read
        if need > max(64 * held, 2 ** 24):
            raise InputError(f"{k} claims {ds.size:.3g} elements ({need} bytes) but stores {held} bytes")
        out[k] = ds[()]
    return out


def _open_regular(path: str, limit: int):
    """A binary file object of ``path`` when it is a regular file of at most ``limit`` bytes
    (``validate.open_regular``, the one checked opener). Returns (file object, size)."""
    from .validate import open_regular
    return open_regular(path, limit, "result file")


def load_result(path: Union[str, os.PathLike]) -> Result:
    """Read a result file written by `save_result` or ``ldaspark integrate --out``.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.json``, ``.npz`` or ``.h5`` file (a str or os.PathLike, not bytes, not a file
        descriptor). Only regular files (checked by ``os.stat`` before opening: a FIFO, a
        device or a link to /dev/zero is refused without blocking; the descriptor read is
        checked again) of at most ``validate.MAX_RESULT_BYTES`` bytes; array headers are
        bounded before the data are read; an HDF5 file that links or stores data outside
        itself is refused before any is read (module docstring).

    Returns
    -------
    Result
        The trajectory and metadata as written.

    Raises
    ------
    InputError
        For NaN, infinity, complex values, wrong shapes and out-of-range metadata (dps outside
        [DPS_MIN, DPS_MAX]), or a file that is not a result file.

    See Also
    --------
    save_result : write a Result.

    Examples
    --------
    >>> import os, tempfile, ldaspark
    >>> res = ldaspark.integrate("skate", "gauss-2", t_span=(0, 1), h=0.5, engine="generic")
    >>> path = os.path.join(tempfile.mkdtemp(), "run.json")
    >>> ldaspark.save_result(res, path)
    >>> back = ldaspark.load_result(path)
    >>> bool(abs(back.q - res.q).max() == 0)
    True
    """
    from .validate import MAX_RESULT_BYTES
    path = check_path(path)
    ext = _ext(path)
    fh, size = _open_regular(path, MAX_RESULT_BYTES)
    with fh:
        return _load(path, ext, fh, size)


def _load(path, ext, fh, size) -> Result:
    try:
        if ext == ".json":
            raw = fh.read(size + 1)
            d = json.loads(raw.decode("utf-8"), parse_constant=_no_constant, parse_float=_finite_float)
            if not isinstance(d, dict):
                raise InputError(f"{os.fspath(path)}: not a result file")
            _check_metadata(d)
            arrays = {}
            maybe_bools = b"true" in raw or b"false" in raw        # the walk only when one can be there
            for k in ARRAYS:
                if k in d:
                    if maybe_bools:
                        _refuse_bools(d[k], k)
                    try:
                        arrays[k] = np.array(d[k], dtype=object if d.get("dps") else float)
                    except (TypeError, ValueError, OverflowError):
                        raise InputError(f"{k} is not an array of numbers (rows of equal length)") from None
            if "psi" in arrays and d.get("dps"):
                arrays["psi"] = np.array(d["psi"], dtype=str) if d["psi"] else np.zeros(0)
            if "psi_shape" in d:
                arrays["psi"] = _json_empty_psi(d)
            for k in ARRAYS:
                if k in arrays and d.get("dps"):
                    arrays[k] = np.asarray(arrays[k]).astype(str)
            res = _build(d, arrays)
            _restore_extras(res, _json_extras(d.get("extra_arrays")))
            return res
        if ext == ".npz":
            z = np.load(fh, allow_pickle=False)
            if not hasattr(z, "files"):          # a bare .npy array under an .npz name
                raise InputError("not an .npz archive")
            with z:
                arrays = _npz_arrays(path, z)
                if "metadata" not in arrays:
                    raise InputError("no metadata array")
                md = json.loads(str(arrays.pop("metadata")), parse_constant=_no_constant,
                                parse_float=_finite_float)
                extra = {k: arrays.pop(k) for k in list(arrays) if _is_extra(k)}
                res = _build(md, arrays)
                _restore_extras(res, extra)
                return res
        h5py = _h5py()
        with h5py.File(fh, "r") as f:
            _h5_check_tree(f)                  # before anything is read
            md = json.loads(_h5_metadata(f, fh), parse_constant=_no_constant, parse_float=_finite_float)
            arrays = _h5_arrays(f)
            extra = {k: arrays.pop(k) for k in list(arrays) if _is_extra(k)}
            res = _build(md, arrays)
            _restore_extras(res, extra)
            return res
    except InputError as exc:
        msg = str(exc)
        if os.fspath(path) in msg:
            raise
        raise InputError(f"cannot read result file {os.fspath(path)}: {msg}") from None
    except RecursionError:
        raise InputError(f"cannot read result file {os.fspath(path)}: JSON nested too deeply") from None
    except (OSError, ValueError, KeyError, TypeError, EOFError, UnicodeDecodeError, json.JSONDecodeError,
            __import__("zipfile").BadZipFile, NotImplementedError, RuntimeError) as exc:
        # corrupt files: zipfile raises NotImplementedError for an unknown compression method,
        # h5py RuntimeError for a damaged symbol table
        why = str(exc).splitlines()[0][:160] if str(exc) else type(exc).__name__
        raise InputError(f"cannot read result file {os.fspath(path)}: {why}") from None
