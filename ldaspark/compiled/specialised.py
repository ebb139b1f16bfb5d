"""The quasi-Newton SPARK kernel specialised per (s, n, m) (issue 48, item 3).

``kernels_quasi`` compiles once for every system: the stage count s, the dimension n and the
number of constraints m are read from array shapes, so LLVM knows no trip count of the many small
loops of the step (s <= 8, n and m often 1-3). ``specialised_source(s, n, m)`` is the text of
``kernels_quasi`` with the residual it calls (``kernels_mech.mech_residual``, ``newton.stage_points``)
copied in and every size on the step's path replaced by the module constants S_, N_, M_, which
numba freezes as compile-time constants. Nothing else changes: the same loops in the same order, no
fast-math, so the specialised kernel returns the same bits as the generic one (tested:
tests/compiled/test_specialised.py), and a run does not depend on which of the two ran.
Measured 1.4-1.5x less CPU per step (``benchmarks/quasi_step.py``, ``per_step``).

The catch is the compile: about 30 s for one (s, n, m) (the Newton fallback chain is compiled in),
which no first call may pay (issue 48: a new model's first step stays within its round-4 time). So
the generic kernel always serves, and the specialised one is built in a separate process
(``lifecycle.run_linked``: it dies with this one) once this process has spent BUILD_AFTER seconds
of CPU in the generic kernel for that (s, n, m) (the build then costs at most as much as was
already spent there); its compiled code lands in the trusted cache (``cache.load_source``: a
generated module whose numba cache is recorded and checked, ``cache.TrustedStore``), from which
this process and later ones load it (``_load``: from the cache only, never compiling in the
caller). ``LDASPARK_SPECIALISE=0`` turns all of it off; ``build(s, n, m)`` builds now (the
benchmarks do, so that both kernels are measured). ``Result.stats["kernel_specialised"]`` says
which kernel ran.
"""
from __future__ import annotations

import os
import re
import sys
import threading
import time

from ..core.errors import InputError

#: CPU seconds in the generic kernel for one (s, n, m) after which its specialised kernel is built
BUILD_AFTER = 30.0
#: CPU seconds in the generic kernel for one (s, n, m) after which the trusted cache is looked in
LOAD_AFTER = 1.0
#: wall seconds a build may take before it is abandoned (the compile takes ~30 s on 2 cores)
BUILD_TIMEOUT = 900.0
#: largest sizes specialised (beyond them the generated loops gain little and compile long)
MAX_S, MAX_N, MAX_M = 16, 31, 31

_HERE = os.path.dirname(os.path.abspath(__file__))
_PREFIX = "ldaspark_quasi_"
_lock = threading.Lock()
_ready: dict = {}            # (s, n, m) -> entry point
_spent: dict = {}            # (s, n, m) -> CPU seconds in the generic kernel
_builds: dict = {}           # (s, n, m) -> the thread waiting for its build process
_failed: dict = {}           # (s, n, m) -> why its build failed (not retried in this process)
_tried: set = set()          # (s, n, m) looked for in the cache since the last build
_load_lock = threading.Lock()  # numba's dispatcher: one thread adds an overload at a time


def _building(key) -> bool:
    """A build of ``key`` is running (a thread object inherited through fork is not alive)."""
    t = _builds.get(key)
    return t is not None and t.is_alive()


def enabled() -> bool:
    return os.environ.get("LDASPARK_SPECIALISE", "1").strip() not in ("0", "off", "no", "false")


def _function(text: str, name: str) -> str:
    m = re.search(r"(@numba\.njit\([^\n]*\)\ndef " + name + r"\(.*?)(?=\n\n\n|\Z)", text, re.S)
    if m is None:
        raise RuntimeError(f"specialised_source: {name} not found")
    return m.group(1)


def _read(name: str) -> str:
    with open(os.path.join(_HERE, name), encoding="utf-8") as f:
        return f.read()


def _in_range(s, n, m) -> bool:
    return 1 <= s <= MAX_S and 1 <= n <= MAX_N and 0 <= m <= MAX_M


def _sizes(s, n, m) -> tuple:
    s, n, m = int(s), int(n), int(m)
    if not _in_range(s, n, m):
        raise InputError(f"no specialised kernel for (s, n, m) = ({s}, {n}, {m}): sizes 1 <= s <= {MAX_S}, "
                         f"1 <= n <= {MAX_N}, 0 <= m <= {MAX_M}")
    return s, n, m


def specialised_source(s, n, m) -> str:
    """``kernels_quasi``'s text for the sizes (s, n, m): see the module docstring. The text
    carries kernels_quasi's HELPERS_SHA256 (and so the digest of every helper compiled into it):
    editing any of them changes the generated module's name and so its cache entry."""
    s, n, m = _sizes(s, n, m)
    src = _read("kernels_quasi.py")
    extra = _function(_read("kernels_mech.py"), "mech_residual") + "\n\n\n" + \
        _function(_read("newton.py"), "stage_points") + "\n\n\n"
    subs = (
        ("from .kernels_mech import mech_residual, mech_workspace",
         "from ldaspark.compiled.kernels_mech import mech_workspace"),
        ("from . import modeltypes as mt", "from ldaspark.compiled import modeltypes as mt\n"
         "from ldaspark.compiled.cache import model_jit as _jit"),
        ("from .kernels import", "from ldaspark.compiled.kernels import"),
        ("from .newton import (", "from ldaspark.compiled.newton import ("),
        ("QUASI_SIG = types.void", f"S_, N_, M_ = {s}, {n}, {m}\n\n\n" + extra + "QUASI_SIG = types.void"),
        ("for a in range(out.shape[0]):", "for a in range(N_):"),
    )
    for old, new in subs:
        if old not in src:
            raise RuntimeError(f"specialised_source: {old!r} not found in kernels_quasi.py")
        src = src.replace(old, new, 1)
    for pat, rep in ((r"^(\s+)s, n, m = [^\n]*$", r"\1s, n, m = S_, N_, M_"),
                     (r"^(\s+)s, m, n = [^\n]*$", r"\1s, m, n = S_, M_, N_"),
                     (r"^(\s+)s, n = [A-Za-z_]+\.shape\[0\], [A-Za-z0-9_]+\.shape\[\d\]$", r"\1s, n = S_, N_"),
                     (r"^(\s+)s = (?:tab\[1\]|A)\.shape\[0\]$", r"\1s = S_"),
                     (r"^(\s+)n = q0\.shape\[0\]$", r"\1n = N_"),
                     (r"^(\s+)n = q\.shape\[0\]$", r"\1n = N_"),
                     (r"^(\s+)m = out_k\.shape\[1\]$", r"\1m = M_")):
        src, k = re.subn(pat, rep, src, flags=re.M)
        if k == 0:
            raise RuntimeError(f"specialised_source: no line matches {pat!r}")
    # every compiled function through the trusted cache of the generated module (cache.model_jit)
    src = src.replace("@numba.njit(cache=True)", "@_jit()")
    src = re.sub(r"@numba\.njit\(cache=True, ([^\n]*)\)", r"@_jit(\1)", src)
    if "@numba.njit" in src:
        raise RuntimeError("specialised_source: a decorator was not converted")
    head = (f'"""Generated by ldaspark.compiled.specialised: kernels_quasi for (s, n, m) = ({s}, {n}, {m}). '
            'Do not edit."""\n')
    return head + src.split('"""', 2)[2].lstrip("\n")


def _module(s, n, m):
    from .cache import load_source
    return load_source(specialised_source(s, n, m), prefix=_PREFIX)


def _signature():
    from .kernels_quasi import QUASI_SIG
    return QUASI_SIG


def _load(s, n, m):
    """The entry point of the specialised kernel if its compiled code is in the trusted cache (or
    already in this process), else None; never compiles."""
    import warnings
    from numba.core.errors import NumbaExperimentalFeatureWarning
    mod = _module(s, n, m)
    disp, sig = mod.quasi_run, _signature()
    cres = disp.overloads.get(tuple(sig.args))
    if cres is not None:
        return cres.entry_point
    cache = getattr(disp, "_cache", None)
    if cache is None or not hasattr(cache, "load_overload"):
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumbaExperimentalFeatureWarning)
        cres = cache.load_overload(sig, disp.targetctx)
    if cres is None:
        return None
    disp.add_overload(cres)
    return cres.entry_point


def build(s, n, m) -> object:
    """Compile the specialised kernel for (s, n, m) in this process (into the trusted cache) and
    return its entry point. What the build process runs; the benchmarks call it directly."""
    import warnings
    from numba.core.errors import NumbaExperimentalFeatureWarning
    s, n, m = _sizes(s, n, m)
    from .cache import _FileLock, cache_dir, check_kernel_cache
    from . import kernels, kernels_general, kernels_mech, kernels_quasi, newton
    check_kernel_cache((kernels, kernels_general, kernels_mech, newton, kernels_quasi))
    # one compile per (s, n, m) on this machine: the workers of an ensemble that reach BUILD_AFTER
    # together wait for the first build (asleep) and then load it
    with _FileLock(os.path.join(cache_dir(), f"{_PREFIX}{s}_{n}_{m}.lock")), _load_lock:
        ep = _load(s, n, m)
        if ep is None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", NumbaExperimentalFeatureWarning)
                ep = _module(s, n, m).quasi_run.compile(_signature())
    with _lock:
        _ready[(s, n, m)] = ep
    return ep


#: the build process (not ``-m``: runpy would execute a second copy of this module, which the
#: package has imported already, and warn about it on stderr)
_BUILD = "import sys; from ldaspark.compiled.specialised import _main; sys.exit(_main(sys.argv[1:]))"


def _command(key) -> list:
    from ..core.lifecycle import python_code     # never imports from the working directory
    return [sys.executable, "-c", python_code(_BUILD), *map(str, key)]


def _build_in_background(key) -> None:
    from ..core import lifecycle
    why = None
    try:
        p = lifecycle.run_linked(_command(key),
                                 timeout=BUILD_TIMEOUT, capture_output=True)
        if p.returncode != 0:
            tail = (p.stderr or b"").decode(errors="replace").strip().splitlines()[-1:] or [""]
            why = f"build process exited {p.returncode}: {tail[0][:200]}"
    except BaseException as exc:            # timeout, stop, no interpreter: the generic kernel serves
        why = f"build not finished: {type(exc).__name__}"
    with _lock:
        if why is not None:
            _failed[key] = why
        _tried.discard(key)                 # the next kernel() call loads what was built
        _builds.pop(key, None)


def kernel(s, n, m):
    """The specialised entry point for (s, n, m) when it is ready, else None (the caller runs the
    generic kernel and reports its CPU time to ``note``). Looks in the trusted cache once this
    process has spent LOAD_AFTER seconds in the generic kernel for these sizes (a load costs
    ~0.3 s, a miss ~30 ms: no short run pays either), and again after its own build finished."""
    key = (int(s), int(n), int(m))
    if not enabled():
        return None
    ep = _ready.get(key)
    if ep is not None:
        return ep
    with _lock:
        if (key in _tried or key in _failed or _building(key) or _spent.get(key, 0.0) < LOAD_AFTER
                or not _in_range(*key)):
            return None
        _tried.add(key)
    try:
        with _load_lock:
            ep = _load(*key)                 # built by another process, or by ours just now
    except Exception as exc:                 # no trusted cache directory, numba internals moved
        with _lock:
            _failed[key] = f"cannot load: {type(exc).__name__}: {str(exc)[:200]}"
        return None
    if ep is not None:
        with _lock:
            _ready[key] = ep
    return ep


def note(s, n, m, cpu: float) -> None:
    """Count ``cpu`` seconds of the generic kernel for (s, n, m); start the build process once
    BUILD_AFTER is reached (one build at a time per process, none for sizes beyond MAX_*)."""
    key = (int(s), int(n), int(m))
    if not enabled() or key in _ready:
        return
    with _lock:
        _spent[key] = _spent.get(key, 0.0) + max(float(cpu), 0.0)
        # key not in _tried: the next kernel() call looks in the cache first
        if (_spent[key] < BUILD_AFTER or key in _failed or key not in _tried
                or any(_building(k) for k in _builds) or not _in_range(*key)):
            return
        t = threading.Thread(target=_build_in_background, args=(key,), name=f"ldaspark-specialise-{key}",
                             daemon=True)
        _builds[key] = t
    t.start()


def status(s, n, m) -> str:
    """'ready', 'building', 'failed: why' or 'not built' for (s, n, m) in this process."""
    key = (int(s), int(n), int(m))
    if key in _ready:
        return "ready"
    if _building(key):
        return "building"
    if key in _failed:
        return "failed: " + _failed[key]
    return "not built"


def _main(argv) -> int:
    if len(argv) != 3 or not all(a.isdigit() for a in argv):
        print("usage: ldaspark.compiled.specialised._main([S, N, M])", file=sys.stderr)
        return 2
    from ..core.errors import LdasparkError
    t0 = time.time()
    try:
        build(*map(int, argv))
    except LdasparkError as exc:
        print(f"ldaspark.compiled.specialised: {exc}", file=sys.stderr)
        return 2
    print(f"built ({', '.join(argv)}) in {time.time() - t0:.1f} s")
    return 0

