"""Argument validation shared by the generic and the compiled paths: every bad option becomes an
InputError (one line at the command line) before any work is done, never a TypeError,
UnboundLocalError or MemoryError from deep inside a loop."""
from __future__ import annotations

import math
import numbers
import os

from .errors import InputError, SystemDefinitionError

#: Newton iteration caps above this are certainly mistakes (each iteration costs a factorisation)
MAX_NEWTON_ITER = 10 ** 6
#: fraction of the physical memory a run may plan to hold (the trajectory arrays)
MEMORY_FRACTION = 0.5


def check_newton_options(tol, max_iter, what: str = "Newton tolerance") -> None:
    """tol: None or a finite positive real number; max_iter: an integer in [1, MAX_NEWTON_ITER]."""
    if tol is not None:
        try:
            # a complex tol (np.complex128(1) converted by float() with a warning) is not a tolerance
            ok = not (_is_bool(tol) or isinstance(tol, (str, bytes, complex))
                      or getattr(getattr(tol, "dtype", None), "kind", "") == "c") \
                and math.isfinite(float(tol)) and float(tol) > 0
        except (TypeError, ValueError, OverflowError):
            ok = False
        if not ok:
            raise InputError(f"{what} must be a finite positive number, got {_repr(tol)}")
    if _is_bool(max_iter) or not isinstance(max_iter, numbers.Integral) or not 1 <= max_iter <= MAX_NEWTON_ITER:
        raise InputError(f"max_iter must be an integer between 1 and {MAX_NEWTON_ITER}, got {_repr(max_iter)}")


def smallest_tol(dps=None):
    """The smallest Newton tolerance the arithmetic can honour: its unit round-off
    (``Backend.eps``: 2^-52 in float64, 10^-dps with mpmath). The stopping limit is tol (|x| +
    |v0|) on increments of the stage values V_i = v0 + Z_i, which carry a rounding of eps (|v0| +
    |Z_i|): a smaller limit asks for increments below one rounding of the numbers they correct,
    which no iteration can show (float64, particle, gauss-2, tol = 1e-25: the generic step ends at
    round-off anyway, the compiled kernels spent 15x its iterations and sent 7 of 10 steps to it)."""
    return 2.0 ** -52 if dps is None else float(f"1e-{int(dps)}")     # the literal a user would type


def check_tol_resolvable(tol, dps=None, what: str = "tol") -> None:
    """tol (already a positive number or None) is at least ``smallest_tol(dps)``: a tolerance the
    arithmetic cannot reach is refused (house rule: honoured or refused, never changed)."""
    if tol is None:
        return
    low = smallest_tol(dps)
    if float(tol) < low:
        arith = "float64" if dps is None else f"{int(dps)}-digit arithmetic"
        more = "; dps= gives more digits" if dps is None else ""
        raise InputError(f"{what} = {_repr(tol)} is below the unit round-off of {arith}: the smallest tol it can "
                         f"honour is {low:.6g} (None: the engine's default){more}")


def check_system_and_tableau(system, tableau) -> None:
    """The integrators' first two arguments have the right types (a clear error, not an
    AttributeError several calls deep). Duck-typed, so that subclasses and variants of
    LagrangianSystem / SparkTableau pass."""
    if not all(hasattr(system, a) for a in ("n", "m", "stage", "momentum", "energy", "saddle_matrix")):
        raise InputError(f"system must be a LagrangianSystem, got {type(system).__name__}")
    if not (hasattr(tableau, "arrays") and isinstance(getattr(tableau, "s", None), int)):
        raise InputError(f"tableau must be a SparkTableau (see ldaspark.core.families.get_method), "
                         f"got {type(tableau).__name__}")


def physical_memory() -> int | None:
    """Bytes of physical memory, or None where the platform does not say."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


#: the advice of ``check_storage``; where the points are the samples ``save_every`` keeps,
#: ``EVERY_ADVICE`` follows it (n_steps = 10**9 at save_every = 1 told only to take fewer steps)
STORAGE_ADVICE = "use fewer steps (a larger h or a shorter t_end)"
EVERY_ADVICE = " or keep fewer samples (a larger save_every; --every at the command line)"


def check_storage(n_points: int, floats_per_point: int, mp: bool = False, what: str = "the trajectory",
                  every: bool = False) -> None:
    """Refuse a run whose stored samples cannot fit in memory (before allocating them): an
    InputError naming the size, instead of a MemoryError or swapping. mpmath numbers cost ~100
    bytes each, float64 8 bytes plus list overhead. ``every``: the points are the samples
    ``save_every`` keeps (the message says so)."""
    per = 120 if mp else 40
    need = int(n_points) * int(floats_per_point) * per
    mem = physical_memory()
    limit = MEMORY_FRACTION * mem if mem else 64 * 2 ** 30
    if need > limit:
        raise InputError(f"storing {what} ({n_points:.3g} points x {floats_per_point} numbers) needs about "
                         f"{need / 2 ** 30:.3g} GiB, more than {limit / 2 ** 30:.3g} GiB: {STORAGE_ADVICE}"
                         + (EVERY_ADVICE if every else ""))


# --- the API boundary: one check per kind of user value ------------------------------------
# ``ldaspark.integrate``, the CLI (through it), ``RunSpec`` / ``run_many`` and the result-file
# readers call these, so that a wrong value is one InputError naming the argument, before any work.

#: mpmath precision range accepted by ``dps``. Below 16 digits mpmath is less precise than float64
#: (whose unit round-off the tolerances of the float64 path are derived from), so a smaller dps is a
#: mistake; 2000 digits is the bound where one gauss-2 step on a 3-dof scene costs ~1 s there
#: (Newton's LU at O(dps^1.6) per operation), and beyond it a run cannot finish in reasonable time
#: (dps = 10**6 ran for minutes before this bound; the audit had its own bound).
DPS_MIN = 16
DPS_MAX = 2000
#: most steps of one run (and of each ensemble member): beyond it a run cannot finish (at ~1 us a
#: step, 10**9 steps are 20 minutes of the fastest kernel); the same limit as ``spark.MAX_STEPS``
MAX_STEPS = 10 ** 9
#: most characters of a number given as a decimal string (h, t_span, q0 at mpmath precision):
#: 2.5 DPS_MAX digits plus sign and exponent; longer strings are refused before conversion
MAX_NUMBER_CHARS = 5000
#: a ``max_stages`` beyond this cannot be built or audited (exact Gauss nodes of degree s; the
#: Newton matrix has s (n + m) + n rows): refused instead of a MemoryError / OverflowError
MAX_STAGES_CEILING = 100
#: result files larger than this are not read (a trajectory of 10**8 float64 numbers is 0.8 GB)
MAX_RESULT_BYTES = 2 ** 31
#: the Newton variants of ``SparkMethod`` (``integrate``'s ``newton`` names; every engine honours
#: them or refuses them: ``ldaspark.core.rootfinder``)
NEWTON_VARIANTS = ("auto", "full", "simplified", "mixed")


def _is_bool(x) -> bool:
    import numpy as np
    return isinstance(x, (bool, np.bool_))


def real_number(x, what: str, *, positive: bool = False, nonzero: bool = False):
    """A finite real number given as int, float, a NumPy scalar, mpmath ``mpf``, a real sympy
    number or a decimal string (kept as given, so that mpmath runs keep its digits). Returns x.
    Refused: bool (``h=True`` is not 1), complex, None, sequences, non-numeric strings, NaN, inf."""
    if type(x) is float and math.isfinite(x) and (x > 0 or not positive) and (x != 0 or not nonzero):
        return x            # the common case, accepted by the checks below
    ok, val = False, None
    if _is_bool(x):
        raise InputError(f"{what} must be a real number, got the bool {x!r}")
    if isinstance(x, str):
        s = x.strip()
        if len(s) > MAX_NUMBER_CHARS:
            raise InputError(f"{what}: a number string of {len(s)} characters (more than {MAX_NUMBER_CHARS})")
        try:
            val = float(s)
            ok = True
        except ValueError:
            raise InputError(f"{what} must be a real number, got the string {_repr(x)}") from None
    elif isinstance(x, numbers.Real) or type(x).__module__ == "decimal":
        try:
            val, ok = float(x), True
        except (TypeError, ValueError, OverflowError):
            val, ok = float("inf"), True
    else:
        # (mpmath's mpf is registered as numbers.Real: it takes the branch above)
        mod = type(x).__module__ or ""
        if mod.startswith("sympy"):
            import sympy
            if isinstance(x, sympy.Expr) and x.is_number and not x.free_symbols:
                try:
                    c = complex(x)
                except (TypeError, ValueError, OverflowError):
                    c = complex("nan")
                if c.imag != 0:
                    raise InputError(f"{what} must be a real number, got {x}")
                ok, val = True, c.real
        elif hasattr(x, "shape") and getattr(x, "shape", None) == () and getattr(x, "dtype", None) is not None \
                and x.dtype.kind in "iuf":
            ok, val = True, float(x)
    if not ok:
        raise InputError(f"{what} must be a real number, got {_describe(x)}")
    if val == 0 and _nonzero(x):
        val = 5e-324            # below float64's range but not zero: h = mpf('1e-400'), "1e-400"
    if not math.isfinite(val):
        raise InputError(f"{what} must be finite, got {_repr(x)}{_range_hint(x)}")
    if positive and not val > 0:
        raise InputError(f"{what} must be positive, got {_repr(x)}")
    if nonzero and val == 0:
        raise InputError(f"{what} must be nonzero, got {_repr(x)}")
    return x


def _range_hint(x) -> str:
    """Why a number that is finite in its own type (the string "1e400", mpf('1e400'), 10**400) is
    refused as not finite: it rounds to inf in float64, the range of every engine's inputs (also at
    dps, where only the digits, not the exponent range, grow; h = "1e400" at 1000 digits was
    refused as "must be finite" with no reason). Empty for NaN, inf and what is not a number."""
    import decimal
    import fractions
    import sys
    big = sys.float_info.max
    try:
        if isinstance(x, str):
            d = decimal.Decimal(x.strip())
            far = d.is_finite() and abs(d) > decimal.Decimal(big)
        elif isinstance(x, decimal.Decimal):
            far = x.is_finite() and abs(x) > decimal.Decimal(big)
        elif isinstance(x, (int, fractions.Fraction)):
            far = abs(x) > big                  # exact comparison with the float
        elif type(x).__name__ == "mpf":
            import mpmath
            far = bool(mpmath.isfinite(x)) and abs(x) > big
        else:
            return ""
    except (ArithmeticError, ValueError, TypeError):
        return ""
    return (" (beyond float64's range, |x| <= 1.8e308, which bounds every engine's inputs, also at dps)"
            if far else "")


def real_value(x, what: str) -> float:
    """A real number computed by user code (an event function's value) as a float: int, float,
    NumPy scalars and 0-d arrays, Fraction, Decimal, mpmath ``mpf``, real sympy numbers (what
    ``real_number`` takes, but no strings and no bools). NaN and infinity are refused."""
    if isinstance(x, (str, bytes)):
        raise InputError(f"{what} must be a real number, got {_describe(x)}")
    real_number(x, what)
    return float(x)


def _nonzero(x) -> bool:
    """x is not zero in its own number type (a decimal string, mpf, sympy number)."""
    try:
        if isinstance(x, str):
            import decimal
            return decimal.Decimal(x.strip()) != 0
        return bool(x != 0)
    except (ArithmeticError, ValueError, TypeError):
        return False


def _repr(x, limit: int = 80) -> str:
    """repr(x) for an error message, at most ``limit`` characters, never raising: an integer of
    more than 4300 digits (or a Fraction or sympy number holding one) raises ValueError in repr,
    which escaped as that ValueError in place of the InputError being formatted (h = 10**5000)."""
    try:
        r = repr(x)
    except Exception:                   # noqa: BLE001 (a number too large to print, a broken __repr__)
        try:
            if isinstance(x, numbers.Integral) or type(x).__name__ == "Integer":
                r = _fmt_int(int(x))
            elif isinstance(x, numbers.Rational) or type(x).__name__ == "Rational":
                r = f"{_fmt_int(int(x.numerator))}/{_fmt_int(int(x.denominator))}"
            else:
                r = f"<{type(x).__name__} that cannot be printed>"
        except Exception:               # noqa: BLE001
            r = f"<{type(x).__name__} that cannot be printed>"
    return r[:limit]


def _describe(x) -> str:
    """A short description of a bad value for an error message (never its full repr)."""
    r = " ".join(_repr(x, 10 ** 4).split())       # one line: the repr of an array or a dict spans several
    return f"{type(x).__name__} {r[:60]}{'...' if len(r) > 60 else ''}"


def count(x, what: str, lo: int = 1, hi: int = MAX_STEPS) -> int:
    """An integer in [lo, hi] (not a bool, not a float): n_steps, save_every, jobs, stages."""
    import numpy as np
    if _is_bool(x) or not isinstance(x, (int, np.integer)):
        raise InputError(f"{what} must be an integer, got {_describe(x)}")
    if not lo <= x <= hi:
        bound = f"{hi:.0e}" if hi >= 10 ** 6 else str(hi)
        raise InputError(f"{what} must be an integer between {lo} and {bound}, got {_fmt_int(x)}")
    return int(x)


def _fmt_int(x) -> str:
    x = int(x)
    if abs(x) < 10 ** 30:
        return str(x)
    # float() of an integer beyond 1e308 overflows and str() beyond 4300 digits raises: the size,
    # floor(log10 |x|) from the bit length, corrected by exact integer comparisons (an exact power
    # of ten is 10^e, not 10^(e - 1))
    # 2^(b-1) <= |x| < 2^b puts log10 |x| within 0.302 above (b - 1) log10 2, so the estimate is
    # floor(log10 |x|) or, by the float product's rounding, one off either way: one step each way
    # (bounded: no loop)
    ax = abs(x)
    e = int((ax.bit_length() - 1) * 0.30102999566398120)
    e -= int(10 ** e > ax)
    e += int(10 ** (e + 1) <= ax)
    return f"{'-' if x < 0 else ''}about 10^{e}"


def check_dps(dps):
    """None (float64) or an integer number of mpmath digits in [DPS_MIN, DPS_MAX]."""
    if dps is None:
        return None
    import numpy as np
    if _is_bool(dps) or not isinstance(dps, (int, np.integer)):
        raise InputError(f"dps must be None (float64) or an integer number of digits, got {_describe(dps)}")
    if not DPS_MIN <= dps <= DPS_MAX:
        raise InputError(f"dps must be between {DPS_MIN} and {DPS_MAX} digits, got {_fmt_int(dps)}")
    return int(dps)


def check_choice(x, what: str, choices) -> str:
    if not isinstance(x, str) or x not in choices:
        raise InputError(f"{what} must be one of {', '.join(map(repr, choices))}, got {_describe(x)}")
    return x


def check_executor(executor):
    """None or a concurrent.futures-style executor (``submit`` and ``map``): an instance, not
    the class (whose unbound ``submit`` would take the first task for ``self``)."""
    if isinstance(executor, type):
        raise InputError(f"executor must be an executor object, got the class {executor.__name__} "
                         f"(create one: {executor.__name__}(...))")
    if executor is not None and not (callable(getattr(executor, "submit", None))
                                     and callable(getattr(executor, "map", None))):
        raise InputError(f"executor must be a concurrent.futures Executor (submit, map), got {_describe(executor)}")
    # the standard library's pools mark shutdown privately (_shutdown: threads, _shutdown_thread:
    # processes); other executors' RuntimeError at submit is caught where work is submitted
    if executor is not None and (getattr(executor, "_shutdown", False) is True
                                 or getattr(executor, "_shutdown_thread", False) is True):
        raise InputError(f"executor {type(executor).__name__} is shut down: it cannot run new work")
    return executor


def is_process_pool(executor) -> bool:
    """``executor`` sends its work to other processes by pickling it (a ``ProcessPoolExecutor``,
    the package's own pools included)."""
    import concurrent.futures as cf
    return isinstance(executor, cf.ProcessPoolExecutor)


def check_picklable(executor, fns, what: str) -> None:
    """With a process pool, every function in ``fns`` must pickle (a local function or a lambda
    does not): refused up front, naming it, instead of a PicklingError from inside the pool.
    Other executors (threads, this process) take any callable."""
    import pickle
    if not is_process_pool(executor):
        return
    for fn in fns:
        try:
            pickle.dumps(fn)
        except Exception as exc:  # noqa: BLE001  (pickle raises PicklingError, AttributeError, TypeError)
            inner = getattr(fn, "g", fn)                  # an Event wraps its function as .g
            name = getattr(inner, "__qualname__", None) or type(inner).__name__
            raise InputError(f"{what} {name} cannot be sent to the process pool {type(executor).__name__}: it does "
                             f"not pickle ({type(exc).__name__}; a local function or a lambda): define it at "
                             "module level, or use a ThreadPoolExecutor") from None


def submitted(executor, future):
    """What ``executor.submit`` returned, checked: a future (``result`` and ``cancel``), else one
    InputError naming the executor (a ``submit`` that returns None was an AttributeError later)."""
    if not (callable(getattr(future, "result", None)) and callable(getattr(future, "cancel", None))):
        raise InputError(f"the executor {type(executor).__name__}'s submit returned {_describe(future)}, not a "
                         "future (concurrent.futures.Future: result, cancel)")
    return future


def submit_error(executor, exc: BaseException) -> InputError:
    """The one-line error for an executor whose ``submit`` raised (shut down, or its own error)."""
    if isinstance(exc, RuntimeError):
        return executor_shut_down(exc)
    return InputError(f"the executor {type(executor).__name__}'s submit raised {type(exc).__name__}: "
                      f"{' '.join(str(exc).split())[:100]}")


def executor_shut_down(exc: BaseException) -> InputError:
    """The one-line error for an executor that refused new work at submit (RuntimeError
    'cannot schedule new futures after shutdown' and the like)."""
    return InputError(f"the executor refused new work ({type(exc).__name__}: {' '.join(str(exc).split())[:100]})")


def real_vector(x, what: str):
    """q0 / v0: a sequence of real numbers (1-D), or rows of them (2-D, an ensemble); entries as
    accepted by ``real_number``. Returns x unchanged (strings and mpf keep their digits)."""
    import numpy as np
    if type(x) is np.ndarray and x.dtype == np.float64 and x.ndim in (1, 2) and x.size and np.isfinite(x).all():
        return x          # finite float64 numbers: what the entry-wise checks below would accept
    if type(x) in (list, tuple) and x and all(type(e) is float and math.isfinite(e) for e in x):
        return x          # a vector of finite floats (a scene's initial data): likewise
    try:
        a = np.asarray(x, dtype=object)
    except (ValueError, TypeError):
        raise InputError(f"{what} must be a list of numbers (rows of equal length), got {_describe(x)}") from None
    if a.ndim not in (1, 2) or a.size == 0:
        raise InputError(f"{what} must be a non-empty vector (or rows of vectors for an ensemble), got {_describe(x)}")
    for i, e in enumerate(a.reshape(-1)):
        real_number(e, f"{what}[{i}]" if a.ndim == 1 else f"{what} entry {i}")
    return x


def param_value(name, value):
    """A parameter value: a real number (strings are parsed by the system's own safe parser)."""
    if isinstance(value, str):
        return value
    return real_number(value, f"parameter {name}")


def check_symbols(q, v) -> None:
    """q and v of a system: sympy Symbols (or functions of t), pairwise distinct, q and v disjoint.
    ``q=[x, x, z]`` or q equal to v would otherwise define a different system silently."""
    import sympy
    allq, allv = list(q), list(v)
    for name, seq in (("q", allq), ("v", allv)):
        for e in seq:
            # numbers and non-sympy values are refused here; functions of t get their own error
            if not isinstance(e, sympy.Expr) or e.is_number:
                raise SystemDefinitionError(f"{name} must be sympy symbols, got {_describe(e)}")
        if len(set(seq)) != len(seq):
            dup = sorted({str(e) for e in seq if seq.count(e) > 1})
            raise SystemDefinitionError(f"{name} lists the same symbol twice: {', '.join(dup)}")
    both = set(allq) & set(allv)
    if both:
        raise SystemDefinitionError(f"q and v share the symbols {', '.join(sorted(map(str, both)))}: "
                         "positions and velocities must be different symbols")


def check_max_stages(max_stages):
    """None (the default limit) or an integer in [1, MAX_STAGES_CEILING]."""
    if max_stages is None:
        return None
    return count(max_stages, "max_stages", 1, MAX_STAGES_CEILING)


def times(t, what: str = "t"):
    """A real finite time, or a 1-D array of them (dense output): float64 array and its ndim.
    Entries as ``real_number`` takes them (mpmath ``mpf``, Fraction, Decimal, real sympy numbers:
    a dps run's own times are mpf)."""
    import numpy as np
    if _is_bool(t) or t is None or isinstance(t, (str, bytes)):
        raise InputError(f"{what} must be a real number or a 1-D array of them, got {_describe(t)}")
    try:
        a = np.asarray(t)
    except (ValueError, TypeError):
        raise InputError(f"{what} must be a real number or a 1-D array of them, got {_describe(t)}") from None
    if a.dtype.kind == "O" and a.ndim <= 1:
        flat = a.reshape(-1)
        vals = []
        for e in flat:
            if isinstance(e, str):
                raise InputError(f"{what} must be a real number or a 1-D array of them, got {_describe(t)}")
            real_number(e, what)
            vals.append(float(e))
        a = np.array(vals, dtype=float).reshape(a.shape)
    if a.dtype.kind not in "iuf" or a.ndim > 1:
        raise InputError(f"{what} must be a real number or a 1-D array of them, got {_describe(t)}")
    a = a.astype(float)
    if not np.all(np.isfinite(a)):
        raise InputError(f"{what} must be finite, got NaN or infinity")
    return a


def regular_file(path, limit: int, what: str = "file") -> int:
    """Size of ``path`` when it is a regular file of at most ``limit`` bytes; ``os.stat`` (which
    follows symbolic links) before anything opens it, so a FIFO never blocks and /dev/zero, or a
    link to it, is never read."""
    import stat
    if isinstance(path, bool) or not isinstance(path, (str, bytes, os.PathLike)):
        raise InputError(f"a {what} path must be a string or os.PathLike, got {_describe(path)}")
    try:
        if "\0" in (os.fsdecode(path) if not isinstance(path, str) else path):
            raise InputError(f"a {what} path must not contain a NUL character")
        st = os.stat(path)
    except FileNotFoundError:
        raise InputError(f"no such {what}: {os.fspath(path)}") from None
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read {what} {os.fspath(path)}: {exc}") from None
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{what} {os.fspath(path)} is not a regular file")
    if st.st_size > limit:
        raise InputError(f"{what} {os.fspath(path)} has {st.st_size} bytes, more than {limit}")
    return st.st_size


def open_regular(path, limit: int, what: str = "file", error=InputError):
    """The one checked opener of every file the library or the command line reads (result
    files, tableau files, JSON inputs): ``(binary file object, size)`` when ``path`` is a
    regular file of at most ``limit`` bytes, else one ``error`` (an LdasparkError subclass) in
    one line. ``regular_file`` (``os.stat``, following links) first, so that a FIFO, a device,
    a directory or a link to one is refused without being opened; then opened without blocking
    (O_NONBLOCK: a FIFO swapped in after the check does not block) and checked again on the
    descriptor: what is checked is what is read."""
    import stat
    try:
        regular_file(path, limit, what)
    except InputError as exc:
        raise (exc if error is InputError else error(str(exc))) from None
    flags = (os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
             | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_BINARY", 0))
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise error(f"cannot read {what} {os.fspath(path)}: {exc.strerror or exc}") from None
    try:
        st = os.fstat(fd)
    except OSError as exc:
        os.close(fd)
        raise error(f"cannot read {what} {os.fspath(path)}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(st.st_mode) or st.st_size > limit:
        os.close(fd)
        raise error(f"{what} {os.fspath(path)} is not a regular file of at most {limit} bytes")
    return os.fdopen(fd, "rb"), st.st_size


def read_regular(path, limit: int, what: str = "file", error=InputError) -> bytes:
    """The bytes of ``path`` through ``open_regular``: at most ``limit`` (a file that grew past
    it since the check is refused, not read to its end)."""
    fh, _ = open_regular(path, limit, what, error)
    try:
        with fh:
            raw = fh.read(limit + 1)
    except OSError as exc:
        raise error(f"cannot read {what} {os.fspath(path)}: {exc.strerror or exc}") from None
    if len(raw) > limit:
        raise error(f"{what} {os.fspath(path)} has more than {limit} bytes")
    return raw


def finite_initial_point(system, bk, t, q, v, member: str = "") -> None:
    """The energy (8) and k at (t, q, v) (converted by ``bk``) are finite real numbers, else one
    NonFiniteError (rather than a NaN, inf or complex result): U = 1/x at x = 0, oo / zoo in L, v0 = 1e200, sqrt(x) at
    x = -1 (math domain error in float64, mpc at dps). Call inside ``bk.context()``."""
    import warnings

    import mpmath
    import numpy as np

    from .errors import NonFiniteError
    # numpy's cast of a complex k to float64 drops the imaginary part with only this warning (k =
    # w + sqrt(-1)*x*v passed as k = w, then failed later as a raw TypeError): an error here
    complex_cast = getattr(getattr(np, "exceptions", np), "ComplexWarning", None)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if complex_cast is not None:
            warnings.simplefilter("error", complex_cast)
        try:
            E = system.energy(bk, t, q, v)
            k = list(system.constraint(bk, t, q, v))
        except Warning as exc:
            raise NonFiniteError(f"{member}L or k has complex values at the initial point t0 = {float(t):g} "
                                 f"({type(exc).__name__}): L and k must be real (I, sqrt of a negative "
                                 "constant)", step=0, time=float(t)) from None
        except (ArithmeticError, ValueError, TypeError) as exc:
            raise NonFiniteError(f"{member}L or k cannot be evaluated at the initial point t0 = {float(t):g} "
                                 f"({type(exc).__name__}: {str(exc)[:80]}): q0, v0 lie outside the domain of "
                                 "L and k", step=0, time=float(t)) from None
    for what, x in [("the energy (8)", E)] + [(f"k[{i}]", x) for i, x in enumerate(k)]:
        ok = (mpmath.isfinite(x) if isinstance(x, mpmath.mpf) else
              isinstance(x, (int, float, np.integer, np.floating)) and math.isfinite(x))
        if not ok:
            raise NonFiniteError(f"{member}{what} at the initial point t0 = {float(t):g} is {str(x)[:60]}, "
                                 "not a finite real number: q0, v0 lie outside the domain of L and k "
                                 "(or L has oo / zoo / I in it)", step=0, time=float(t))


#: id(system) -> (system, {checked float64 initial point: True}) of ``initial_point``: a repeated
#: short run (the per-call overhead of the compiled engine) skips the checks of a point that passed
#: for this system object (the verdict is a function of (system, t0, q0, v0, tol) only); the
#: identity test guards against reuse of ids. Bounded: 256 systems, 64 points each.
_CHECKED: dict = {}


def warn_singular_lvv(system, notes: dict, stacklevel: int = 2) -> None:
    """A run that ended well from a point where L_vv is singular while (4) holds (``notes`` of
    ``initial_point``): (5), the regular Lagrangian, fails, and the stage equations (21) need not
    determine the stage velocities. The numbers may be a root the method does not define (gauss-1
    on L = (vx + vy)^2 / 2 - U, k = vx - vy: the two engines 2-9e-2 apart, both status 0), so the
    result comes with one LdasparkWarning: a single run's (``solve._warn_regular``) and each such
    member's of run_many, the same text."""
    import warnings

    from .errors import LdasparkWarning
    warnings.warn(singular_lvv_message(system, notes), LdasparkWarning, stacklevel=stacklevel + 1)


def singular_lvv_message(system, notes: dict) -> str:
    """The text of ``warn_singular_lvv``."""
    return (f"{system.name}: L_vv is singular at t = {notes['t']:g} (reciprocal condition "
            f"{notes['lvv_rcond']:.2e} after equilibration): the regular Lagrangian (5) fails while (4) "
            "holds, so the stage equations (21) need not determine the stage velocities; a Gauss method "
            "can then converge to different roots on different engines. Compare with another method or "
            "step size")


def initial_point(system, bk, t0, q0, v0, *, member: str = "", project: bool = False, tol=None,
                  consistent: bool = True, model=None, notes: dict | None = None):
    """The one initial-point check of every engine and entry point: (t0, q0, v0) converted by
    ``bk`` (call inside ``bk.context()``), returned as (t, q, v) with v projected onto k = 0 when
    ``project``. In order, each failure one error (``member`` prefixes its message, e.g.
    "ensemble member 3: "):

    1. numbers of the right shapes (n entries each) -> InputError;
    2. finite values -> InputError;
    3. the energy (8) and k of (1c) finite real numbers (``finite_initial_point``) -> NonFiniteError;
    4. with ``consistent`` (the set-up of a run): the saddle matrix (4) regular with K of full rank
       -> SingularSaddleError; then v projected (``project``); then |k(t0, q0, v0)| <= tol' (1 + |v0|)
       (1c) with tol' = 10 tol, or the backend's default when ``tol`` is None ->
       InconsistentInitialDataError.

    ``notes``: a dict that gets what the check found without refusing (a singular L_vv while (4)
    holds: "lvv_rcond", "t"; ``System.check_saddle``).
    ``model(t, q, v) -> (S, k)`` or None: the matrix (4) and k from the caller's own model (the
    compiled engine's generated functions), the same tests applied. A float64 point that passed for
    this system object (without ``project``) is remembered, so repeating a run skips the checks."""
    from .errors import LdasparkError
    try:
        t = bk.scalar(t0)
        q, v = bk.array(q0), bk.array(v0)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{member}t0, q0 and v0 must be numbers: {exc}") from None
    if q.shape != (system.n,) or v.shape != (system.n,):
        raise InputError(f"{member}initial data have shapes q: {q.shape}, v: {v.shape}; the system has "
                         f"n = {system.n}")
    key = memo = None
    if consistent and not project and not bk.is_mp:
        # a remembered point passed every check below (finite values included): the same bytes
        # are the same numbers
        key = (float(t), q.tobytes(), v.tobytes(), tol)
        memo = _CHECKED.get(id(system))
        if memo is not None and memo[0] is system and key in memo[1]:
            if notes is not None and memo[1][key] is not True:
                notes.update(memo[1][key])          # what the check found there (a singular L_vv)
            return t, q, v
    if not (math.isfinite(float(t)) and bk.isfinite(q) and bk.isfinite(v)):
        raise InputError(f"{member}initial data contain NaN or infinity")
    finite_initial_point(system, bk, t, q, v, member)
    if not consistent:
        return t, q, v
    try:
        S, k = (None, None) if model is None else (model(t, q, v) or (None, None))
        found: dict = {}
        system.check_saddle(bk, t, q, v, S=S, notes=found)
        if notes is not None:
            notes.update(found)
        if project:
            v, k = system.project_velocity(bk, t, q, v), None
        system.check_consistent(bk, t, q, v, tol=None if tol is None else 10 * tol, k=k)
    except LdasparkError as exc:
        if not member:
            raise
        raise type(exc)(f"{member}{exc}") from None
    if key is not None:
        if memo is None or memo[0] is not system:
            if len(_CHECKED) >= 256:         # bounded: a parameter sweep makes a new system per value
                _CHECKED.clear()
            memo = _CHECKED[id(system)] = (system, {})
        if len(memo[1]) >= 64:
            memo[1].clear()
        memo[1][key] = dict(found) if found else True
    return t, q, v


# --- the exported functions outside ``integrate`` ------------------------------------------------
# ``flow_jacobian``, the Theorem 1 checks, ``RunSpec`` / ``run_many`` and ``get_scene`` take the
# same kinds of values as ``integrate``; these helpers check them the same way, so that every
# exported name refuses a wrong value with one InputError naming it, before any work.

def point(system, t0, q0, v0, what: str = "", scene=None, dps=None, names=("q0", "v0")):
    """(t0, q0, v0) checked: t0 a real number, q0 and v0 vectors of n real numbers; None takes
    the scene's initial data (when ``scene`` is given). ``names``: what the caller calls the two
    vectors in its messages (``discrete_lagrangian`` checks its q1 in v0's place)."""
    import numpy as np
    if scene is not None and (q0 is None or v0 is None or t0 is None):
        ts, qs, vs = scene.initial(dps)
        t0 = ts if t0 is None else t0
        q0 = qs if q0 is None else q0
        v0 = vs if v0 is None else v0
    if q0 is None or v0 is None:
        raise InputError(f"{what}give q0 and v0 (or a Scene / scene name for its initial data)")
    real_number(t0, f"{what}t0")
    for name, x in zip(names, (q0, v0)):
        real_vector(x, f"{what}{name}")
        if np.ndim(np.asarray(x, dtype=object)) != 1 or len(x) != system.n:
            raise InputError(f"{what}{name} must have n = {system.n} entries, got {_describe(x)}")
    return t0, q0, v0


def step_advances(t0, h, n_steps=1, dps=None, what: str = "h", *, s=None, n=None, m=None) -> None:
    """The times t0 + i h (i = 0..n_steps) are distinct at the working precision: float64 (dps
    None) or ``dps`` digits, and the run's work is within ``check_work``'s bound (``s``, ``n``,
    ``m``: the stages, coordinates and constraints of the problem, when known). A step below the
    spacing of the numbers near t (t0 = 1e17, h = 1 in float64) leaves t where it was, or rounds
    several output times to one, while the state moves by h: refused, naming the smallest step
    that resolves."""
    import numpy as np
    if dps is None:
        h_, t_ = abs(float(h)), abs(float(t0))
        T = max(t_, abs(float(t0) + int(n_steps) * float(h))) if math.isfinite(t_) else t_
        need = 2 * float(np.spacing(T)) if T > 0 else 0.0
        if h_ == 0:
            # a nonzero h below float64's range ("1e-400", "1e-99999999": nonzero in its own digits):
            # it read "h = 0 does not advance t near 0 ...: use |h| >= 0 or a t0 closer to 0"
            raise InputError(f"{what} = {(h if isinstance(h, str) else _repr(h))[:40]} does not advance t in float64: "
                             "it rounds to 0 there (float64 holds |h| >= 5e-324; a step that small needs dps= digits)")
        if h_ < need or float(t0) + float(h) == float(t0):
            raise InputError(f"{what} = {float(h):.3g} does not advance t near {T:.3g} in float64 (times would "
                             f"repeat): use |h| >= {need:.3g} or a t0 closer to 0")
    else:
        # in mpf: 10^(1 - dps) is below float64's range from dps ~ 310 on (a float need of 0.0
        # accepted h = 1e-420 at 400 digits, t0 = 1: every time equal), and so is such an h
        import mpmath
        from .backend import _mpf
        with mpmath.workdps(int(dps) + 10):
            h_, t_ = abs(_mpf(h)), abs(_mpf(t0))
            T = max(t_, abs(_mpf(t0) + int(n_steps) * _mpf(h)))
            need = 2 * T * mpmath.mpf(10) ** (1 - int(dps))
            # the bound is two units of the digits; a float h given at that bound (2 * 10.0**-29,
            # 1 ulp below 2e-29) is not refused for the last bits of the factor
            if not h_ * (1 + mpmath.mpf(2) ** -40) >= need:
                raise InputError(f"{what} = {mpmath.nstr(_mpf(h), 3)} does not advance t near {mpmath.nstr(T, 3)} "
                                 f"in {dps} digits (times would repeat): use |h| >= {mpmath.nstr(need, 3)} "
                                 f"or a t0 closer to 0")
    # the time grid is the run's plan: its work (digits x steps x stage system) is bounded here,
    # before any step
    check_work(n_steps, dps, s=s, n=n, m=m)


#: the work budget of one mpmath run, in steps at low precision (``mp_step_cost(dps) = 1`` up to
#: about 100 digits, for a stage system up to the robot's with gauss-3): at the ~5-10 ms a step of
#: the generic mpmath engine on the paper's scenes (gauss-2 particle 5 ms, gauss-3 robot 7 ms at
#: 50 digits, measured), 2 * 10**6 such steps are 3-6 hours; dps = 2000 (cost ~12.8) is allowed
#: ~1.6 * 10**5 steps (the robot measured 96 ms a step there: ~4 hours), dps = 2000 with 10**6
#: steps (~27 hours) is refused
MP_WORK_MAX = 2 * 10 ** 6


def stage_work(s: int, n: int, m: int) -> float:
    """Operations of one Newton iteration on the stage system of ``s`` stages, ``n`` coordinates
    and ``m`` constraints: N = s (n + m) + n unknowns, the dense LU ~N^3 / 3, the residual and
    Jacobian evaluations ~25 s (n + m), and a fixed ~500 of the step's own bookkeeping. The
    constants are fitted to the generic engine at 300 digits (2 cores, shared and loaded; one to
    four steps each): robot gauss-3 (N = 22) 50 ms a step, particle gauss-2 (N = 11) 6.8 ms at 50
    digits against the robot's 27 ms, mp-particles-nh gauss-4 (N = 39) 255 ms and gauss-10
    (N = 87) 2.6 s: ratios to the robot 0.25, 5.1, 51.5 where this formula gives 0.25, 4.7, 49."""
    N = s * (n + m) + n
    return 500.0 + 25.0 * s * (n + m) + N ** 3 / 3.0


#: ``stage_work`` of the calibration problem of ``mp_step_cost``: the robot (n = 4, m = 2), gauss-3
REF_STAGE_WORK = stage_work(3, 4, 2)


def mp_step_cost(dps: int, s=None, n=None, m=None) -> float:
    """Cost of one step at ``dps`` digits, in steps at low precision of the robot with gauss-3.

    The digits alone: 1 + (dps / 300)^1.3, the generic engine's measured growth on the robot
    (96 ms a step at 2000 digits against 7.2 ms at 50: ratio 13; the formula gives 12.8 at 2000,
    1.1 at 50); mpmath's multiplication is O(dps^1.6) asymptotically, but below ~3000 digits the
    interpreter's fixed cost per operation dominates such a small step.

    With the problem's ``s``, ``n``, ``m`` (all three, else the digits alone), times the size of
    its stage system against the robot's, r = stage_work(s, n, m) / REF_STAGE_WORK, when r > 1
    (a smaller system keeps the digits-alone cost: its fixed per-step cost does not shrink with
    it): 1 + (r - 1) (1 + dps / 1000). The work beyond the robot's is arithmetic on dps-digit
    numbers in the LU and the Jacobian, and grows faster with the digits than the robot's
    interpreter-bound step: mp-particles-nh gauss-4 took 2.1-2.6 s a step at 2000 digits against
    the robot's 0.18 s (same machine as ``stage_work``: ratio 12-14, the formula 12.0), and gauss-10
    ~30 s (the reported case; the formula 146 x the robot's 0.18 s = 26 s)."""
    cost = 1.0 + (max(int(dps), 0) / 300.0) ** 1.3
    if s is None or n is None or m is None:
        return cost
    r = stage_work(int(s), int(n), int(m)) / REF_STAGE_WORK
    return cost * (1.0 + (r - 1.0) * (1.0 + max(int(dps), 0) / 1000.0)) if r > 1 else cost


#: a float64 step of the generic engine (Python loops over numpy arrays), in ``check_work``'s unit
#: (the robot's gauss-3 step at low precision): the robot with gauss-3 and the particle with
#: gauss-2 took 1-2 ms a float64 generic step against 7.2 and 5 ms at 50 digits (measured, shared
#: host); 0.3 keeps ~7 * 10**6 such steps (2-4 hours) and refuses the 10**9 that ``MAX_STEPS``
#: alone let through (weeks). The compiled engine is bounded by ``MAX_STEPS`` alone (~1 us a step).
FLOAT_GENERIC_STEP_COST = 0.3


def check_work(n_steps, dps, what: str = "this run", *, s=None, n=None, m=None,
               float_generic: bool = False) -> float:
    """The work bound of an mpmath run, fixed before it starts: ``n_steps * mp_step_cost(dps, s,
    n, m)`` at most ``MP_WORK_MAX`` (float64 runs, ``dps`` None, are bounded by ``MAX_STEPS``
    alone, except on the generic engine, ``float_generic``: ``FLOAT_GENERIC_STEP_COST`` times the
    size factor of ``mp_step_cost`` a step; without ``s``, ``n``, ``m`` the cost of the digits
    alone). Returns the estimate; refuses with one InputError naming the estimate, the limit and
    what to reduce (docs/reliability.md, "Every unit of work is bounded")."""
    if dps is None and not float_generic:
        return float(n_steps)
    if dps is None:
        cost = FLOAT_GENERIC_STEP_COST * mp_step_cost(0, s, n, m)
        where, fewer = "in float64 on the generic engine", " (or engine='compiled')"
    else:
        cost = mp_step_cost(dps, s, n, m)
        where, fewer = f"at dps = {int(dps)}", " or fewer digits"
    work = int(n_steps) * cost
    if work > MP_WORK_MAX:
        fits = int(MP_WORK_MAX // cost)
        sized = s is not None and n is not None and m is not None
        size = (f" with s = {int(s)} stages, n = {int(n)}, m = {int(m)} (a stage system of "
                f"{int(s) * (int(n) + int(m)) + int(n)} unknowns: {cost:.3g} low-precision steps each)" if sized
                else f" ({cost:.3g} low-precision steps each)")
        if sized:
            fewer = (", fewer digits or fewer stages" if dps is not None
                     else ", fewer stages or engine='compiled'")
        raise InputError(f"{what}: {_fmt_int(int(n_steps))} steps {where}{size} is an estimated work "
                         f"of {work:.3g} low-precision steps, more than the limit {MP_WORK_MAX:.3g}: use at most "
                         f"{fits} steps there (a larger h or a shorter t_end){fewer}")
    return work


def index_list(x, size: int, what: str, unique: bool = True) -> list:
    """A list of integer indices in [0, size) (numpy integers accepted; no bools, floats,
    negative indices or, with ``unique``, repeats)."""
    import numpy as np
    if isinstance(x, (str, bytes, dict)) or not hasattr(x, "__iter__"):
        raise InputError(f"{what} must be a list of indices, got {_describe(x)}")
    out = []
    for e in list(x):
        if _is_bool(e) or not isinstance(e, (int, np.integer)):
            raise InputError(f"{what}: indices must be integers, got {_describe(e)}")
        if not 0 <= e < size:
            raise InputError(f"{what}: index {_fmt_int(e)} out of range 0..{size - 1}")
        out.append(int(e))
    if unique and len(set(out)) != len(out):
        raise InputError(f"{what} lists the same index twice: {out}")
    return out


def callable_or_none(f, what: str):
    if f is not None and not callable(f):
        raise InputError(f"{what} must be callable (or None), got {_describe(f)}")
    return f


def flag(x, what: str) -> bool:
    """True or False (NumPy bools too); anything else (1, "yes", None) is refused."""
    if not _is_bool(x):
        raise InputError(f"{what} must be True or False, got {_describe(x)}")
    return bool(x)


def _rational_string(x):
    """A string "p/q" (integers, q nonzero, at most MAX_NUMBER_CHARS characters) as a Fraction,
    else None."""
    import re
    from fractions import Fraction
    if not isinstance(x, str) or len(x) > MAX_NUMBER_CHARS:
        return None
    m = re.fullmatch(r"\s*([+-]?\d+)\s*/\s*(\d+)\s*", x)
    try:
        if m is None or int(m.group(2)) == 0:
            return None
        return Fraction(int(m.group(1)), int(m.group(2)))
    except ValueError:                  # more digits than int() converts
        return None
