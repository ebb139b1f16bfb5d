"""The JSON tableau file: reading the coefficients c, A, A_hat, A_tilde, b, b_hat, b_tilde and
omega of (21) from a file (the format of ``ldaspark audit``, ``docs/audit.md``).

``load_tableau`` reads a bounded regular file (``max_file_bytes``), keeps JSON numbers as their
decimal texts (``_json_number``) and hands the object to ``from_json_dict``, which checks the stage
count (``check_stages``, at most ``MAX_STAGES`` unless raised), the shapes, and reads every entry
through the entry language of ``ldaspark.core.numbers`` (exact strings parsed by a whitelist, never
evaluated; decimal digits recorded; float64 entries). omega defaults to omega_ij = b_j c_j^(i-1)
as after (21f); ``_rank_checked`` refuses a tableau whose omega has rank below s-1 at the precision
its entries carry (``omega_rank``): (21e) with (21f) would not determine the s multipliers.
"""
from __future__ import annotations

import json

import sympy

from .errors import TableauError
from .numbers import FLOAT64_REPR_DIGITS, LONG_DECIMAL, MAX_STAGES, JsonNumber, _parse_entry, fixed_places
from .tableau import NAMES, VECTOR_NAMES, SparkTableau, _col, _default_omega_exact, _flatten, omega_rank


def check_stages(s: int, max_stages: int | None = None, what: str = "tableau") -> None:
    """s <= max_stages (default MAX_STAGES = 20): building, auditing and integrating cost grows
    like s^3 and beyond, so larger s must be asked for explicitly."""
    from .validate import MAX_STAGES_CEILING
    limit = MAX_STAGES if max_stages is None else max_stages
    if type(limit).__module__ == "numpy" and hasattr(limit, "dtype") and limit.dtype.kind in "iu":
        limit = int(limit)                   # np.int64(3) is an integer like 3
    if isinstance(limit, bool) or not isinstance(limit, int) or not 1 <= limit <= MAX_STAGES_CEILING:
        # --max-stages 10**6 was a MemoryError, 10**8 an OverflowError
        raise TableauError(f"max_stages must be an integer between 1 and {MAX_STAGES_CEILING}, got "
                           f"{limit if abs(limit) < 10 ** 12 else f'{float(limit):.3g}'}"
                           if isinstance(limit, int) else f"max_stages must be an integer, got {type(limit).__name__}")
    if s > limit:
        raise TableauError(f"{what} has s = {s} stages, more than the limit {limit} "
                           "(raise it with --max-stages / max_stages=)")


def from_json_dict(d: dict, name: str | None = None, max_stages: int | None = None) -> SparkTableau:
    """Tableau from the JSON format (keys c, A, A_hat, A_tilde, b, b_hat, b_tilde, optional
    omega and name). Exact when every entry is an int or string, else float precision.
    At most ``max_stages`` (default MAX_STAGES) stages."""
    if not isinstance(d, dict):
        raise TableauError("tableau JSON must be an object with keys c, A, A_hat, A_tilde, b, b_hat, b_tilde")
    _refuse_misspelt_keys(d)
    missing = [k for k in NAMES if k != "omega" and k not in d]
    if missing:
        raise TableauError(f"tableau is missing key(s): {', '.join(missing)}")
    c = d["c"]
    if not isinstance(c, list) or not c:
        raise TableauError("c must be a non-empty list")
    s = len(c)
    check_stages(s, max_stages)
    all_exact = True
    ex = {}
    info = {"digits": 0}
    for k in NAMES:
        if k not in d:
            continue
        val = d[k]
        if k in VECTOR_NAMES:
            if not isinstance(val, list) or len(val) != s or any(isinstance(v, list) for v in val):
                raise TableauError(f"{k} must be a list of {s} numbers")
            ent = [_parse_entry(v, f"{k}[{i}]", info) for i, v in enumerate(val)]
            ex[k] = _col([e for e, _ in ent])
        else:
            rows = s - 1 if k == "omega" else s
            if (not isinstance(val, list) or len(val) != rows
                    or any(not isinstance(r, list) or len(r) != s for r in val)):
                raise TableauError(f"{k} must be a {rows} x {s} list of lists")
            ent = [[_parse_entry(v, f"{k}[{i}][{j}]", info) for j, v in enumerate(r)] for i, r in enumerate(val)]
            ex[k] = sympy.Matrix(rows, s, [e for r in ent for e, _ in r]) if rows else sympy.zeros(0, s)
            ent = [e for r in ent for e in r]
        all_exact = all_exact and all(flag for _, flag in ent)
    if "omega" not in ex:
        ex["omega"] = _default_omega_exact([ex["b"][j] for j in range(s)], [ex["c"][j] for j in range(s)], s)
    # a "name" that is not a string ({"a": 1}, 5, "") was str()-ed or replaced by "custom" in silence:
    # it gets the rule of SparkTableau's name (a non-empty printable string of at most 500
    # characters: it is printed and written as the method's name); null or absent is "custom"
    label = name if name is not None else d.get("name") if d.get("name") is not None else "custom"
    # the entries as given, so that the audit decides at the precision they carry
    sources = {k: [list(r) if isinstance(r, list) else r for r in d[k]] for k in NAMES if k in d}
    digits = info["digits"] or None
    longs = [n for n in info.get("counts", ()) if n >= LONG_DECIMAL]
    kw = dict(family="custom", sources=sources, decimal_digits=digits, decimal_digits_min=min(longs) if longs else None,
              decimal_places=fixed_places(info.get("shapes", ())) if digits else None)
    if all_exact:
        return _rank_checked(SparkTableau(label, s, exact=ex, **kw))
    # float64 entries carry ~15 digits; JSON numbers longer than a float64's writing their own
    pyfloat = any(isinstance(x, float) for v in sources.values() for x in _flatten(v))
    jd = info.get("json")
    digits_carried = jd if jd is not None and jd > FLOAT64_REPR_DIGITS and not pyfloat else 15
    return _rank_checked(SparkTableau(label, s, exact=ex, source_digits=digits_carried, **kw))


def _key_form(k: str) -> str:
    return "".join(ch for ch in k.lower() if ch not in "_- ")


def _refuse_misspelt_keys(d: dict) -> None:
    """Keys besides the tableau's are metadata ("comment", "source") and ignored, but one that is a
    near miss of a tableau key ("Omega", "omgea", "A-hat": the same letters up to case and _ - space,
    or a difflib ratio >= 0.8) is refused naming the key meant: ignored, a misspelt omega made the
    audit judge the default omega instead of the file's."""
    import difflib
    known = NAMES + ("name",)
    for k in d:
        if not isinstance(k, str) or k in known:
            continue
        same = [n for n in known if _key_form(n) == _key_form(k)]
        near = same or difflib.get_close_matches(k, known, n=1, cutoff=0.8)
        if near:
            raise TableauError(f"tableau key {k[:40]!r} is not one of {', '.join(known)}: did you mean {near[0]!r}?")


def _rank_checked(tab: SparkTableau) -> SparkTableau:
    """``tab`` when omega has rank s-1 at the precision its entries carry (``omega_rank``), else a
    TableauError: (21e) with (21f) would not determine the s multipliers."""
    if tab.s > 1:
        r = omega_rank(tab)
        if r["rank"] < tab.s - 1:
            sig = r["sigma"][tab.s - 2] if len(r["sigma"]) >= tab.s - 1 else 0.0
            raise TableauError(f"omega is singular (rank {r['rank']} < s-1 = {tab.s - 1}: its smallest singular "
                               f"value {sig:.2e} is within {r['bound']:.1e}, the uncertainty of the entries and "
                               f"of {r['dps']}-digit arithmetic): (21e) would not determine the multipliers")
    return tab


def _json_number(text: str):
    """``parse_float`` of the tableau loader: the text of a JSON number (JsonNumber), also one
    beyond float64 (1e999999), which ``_parse_entry`` refuses naming the text written (as a float
    it read "entry inf is not finite"). NaN and Infinity are JSON constants, not numbers: they
    stay floats (``parse_constant``) and are refused as not finite."""
    return JsonNumber(text)


class _DuplicateKey(Exception):
    """A key given twice in one JSON object of a tableau file (``_unique_keys``)."""


def _unique_keys(pairs) -> dict:
    """``object_pairs_hook`` of the tableau loader: json.loads keeps the last of two equal keys in
    silence, and the audit judged whichever of two A_hat came last; a key given twice is refused."""
    d = {}
    for k, v in pairs:
        if k in d:
            raise _DuplicateKey(str(k)[:40])
        d[k] = v
    return d


def max_file_bytes(max_stages: int | None = None) -> int:
    """Largest tableau file read: 4000 bytes per coefficient slot (s^2 of them), at least 1 MiB."""
    s = MAX_STAGES if max_stages is None else max_stages
    check_stages(1, max_stages)          # max_stages itself in range before it sizes anything
    return max(2 ** 20, 4000 * s * s)


def load_tableau(path, max_stages: int | None = None) -> SparkTableau:
    """Read a tableau JSON file (the format of ``ldaspark audit``).

    Entries may be exact strings ("1/2", "sqrt(3)/6", parsed by a whitelist, never evaluated),
    decimal strings (their digits are recorded) or float64 numbers.

    Parameters
    ----------
    path : str or os.PathLike
        A regular file of at most ``max_file_bytes(max_stages)`` bytes (never /dev/zero, a
        FIFO or a directory).
    max_stages : int, optional
        Stage limit (default 20).

    Returns
    -------
    SparkTableau
        The tableau, with ``precision_kind`` telling what its entries carry.

    Raises
    ------
    TableauError
        Naming the problem (a missing entry, a wrong shape, an unparsable string).

    Examples
    --------
    >>> import json, os, tempfile, ldaspark
    >>> midpoint = {"name": "midpoint", "c": ["1/2"], "A": [["1/2"]], "A_hat": [["1/2"]],
    ...             "A_tilde": [["1/2"]], "b": ["1"], "b_hat": ["1"], "b_tilde": ["1"]}
    >>> path = os.path.join(tempfile.mkdtemp(), "midpoint.json")
    >>> with open(path, "w") as f:
    ...     json.dump(midpoint, f)
    >>> ldaspark.load_tableau(path).s
    1
    """
    import os
    if isinstance(path, bool) or not isinstance(path, (str, bytes, os.PathLike)) \
            or "\0" in (path if isinstance(path, str) else os.fsdecode(path)):
        raise TableauError(f"a tableau path must be a file name (str or os.PathLike, no NUL), got "
                           f"{type(path).__name__} {str(path)[:60]!r}")
    from .validate import read_regular
    limit = max_file_bytes(max_stages)
    try:
        # the one checked opener: a regular file of bounded size, checked again on the descriptor
        if not os.path.exists(path):
            if os.path.lexists(path):       # a link loop is not "not found": say what it is
                raise TableauError(f"tableau file {os.fsdecode(path)} is a symbolic link that does not resolve "
                                   "(its target is missing or the links form a loop)")
            raise FileNotFoundError(path)
        raw = read_regular(path, limit, "tableau file", TableauError)
        # a JSON number is a decimal text with its digits (JsonNumber): 0.1127016653792583 is known
        # to its 16 digits and half an ulp, a published 15-digit coefficient to its 15 digits
        # utf-8-sig: a byte-order mark (Windows editors) is not part of the JSON text
        d = json.loads(raw.decode("utf-8-sig"), parse_float=_json_number, object_pairs_hook=_unique_keys)
    except FileNotFoundError:
        raise TableauError(f"tableau file {path} not found") from None
    except _DuplicateKey as exc:
        raise TableauError(f"tableau file {path}: key {exc.args[0]!r} is given twice") from None
    except json.JSONDecodeError as exc:
        raise TableauError(f"tableau file {path} is not valid JSON: {exc.msg} at line {exc.lineno}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TableauError(f"cannot read tableau file {path}: {exc}") from None
    except ValueError as exc:       # e.g. an integer of more than 4300 digits
        why = ("an integer literal has too many digits" if "integer string conversion" in str(exc)
               else str(exc).splitlines()[0][:120])
        raise TableauError(f"tableau file {path} is not valid JSON: {why}") from None
    except RecursionError:
        raise TableauError(f"tableau file {path} is not valid JSON: nested too deeply") from None
    return from_json_dict(d, max_stages=max_stages)
