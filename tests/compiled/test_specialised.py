"""The quasi-Newton kernel specialised per (s, n, m) (``ldaspark.compiled.specialised``).

It is the generic kernel's text with the sizes as constants, so it must return the same bits:
every output array and counter of ``run_quasi`` is compared for equality (not to a tolerance) on
runs that reach each branch of the step loop (the M-only iteration on the skate, the curvature
block on the particle, the Newton fallback chain on the particle at h = 1, 165 of 200 steps). The
negative control shows the comparison sees a last-bit change (Kahan summation off). Then the
choice: used by ``integrate`` when ready and said so in the stats, never when
LDASPARK_SPECIALISE=0; a build process started once BUILD_AFTER seconds were spent, its result
loaded; a failed build leaves the generic kernel, once. The first (2, 3, 1) build compiles for
~30 s (then numba's cache, in the trusted cache directory, serves it in ~0.3 s).
"""
import sys
import time

import numpy as np
import pytest
from hypothesis import given, settings

import ldaspark
from ldaspark.compiled import quasi as Q
from ldaspark.compiled import runner
from ldaspark.compiled import specialised as SP
from ldaspark.core.errors import LdasparkError
from ldaspark.models.scenes import get_scene
from verification.harness import mechanical_cases

KEY = (2, 3, 1)
RUNS = (("skate", 0.1, 300), ("particle", 0.2, 300), ("particle", 1.0, 200))


@pytest.fixture(scope="module")
def built():
    return SP.build(*KEY)


@pytest.fixture
def registry(monkeypatch):
    """A fresh registry of this process, the feature on."""
    monkeypatch.setenv("LDASPARK_SPECIALISE", "1")
    for name in ("_ready", "_spent", "_builds", "_failed"):
        monkeypatch.setattr(SP, name, {})
    monkeypatch.setattr(SP, "_tried", set())
    return SP


def _run(scene, h, n_steps, ep, monkeypatch, compensated=True):
    sc = get_scene(scene)
    cs = runner.compile_system(sc.system)
    monkeypatch.setattr(SP, "kernel", lambda s, n, m: ep)
    monkeypatch.setattr(SP, "note", lambda *a: None)
    t0, q0, v0 = sc.initial()
    return Q.run_quasi(cs, "gauss-2", t0, q0, v0, h, n_steps, 1, compensated)


def _same(a, b):
    for name in ("t", "q", "v", "energy", "constraint"):
        x, y = getattr(a, name), getattr(b, name)
        assert np.array_equal(x, y), (name, np.max(np.abs(x - y)))
    assert np.array_equal(a.psi, b.psi)
    for k in Q.QUASI_STAT_NAMES + ("steps", "newton_iterations", "nfev", "njev", "nlu", "max_iterations",
                                   "full_newton_steps"):
        assert a.stats[k] == b.stats[k], k


@pytest.mark.parametrize("scene,h,n_steps", RUNS)
def test_the_specialised_kernel_returns_the_generic_kernels_bits(built, monkeypatch, scene, h, n_steps):
    gen = _run(scene, h, n_steps, None, monkeypatch)
    spec = _run(scene, h, n_steps, built, monkeypatch)
    assert gen.stats["kernel_specialised"] is False and spec.stats["kernel_specialised"] is True
    _same(gen, spec)
    if h == 1.0:
        assert spec.stats["quasi_fallbacks"] > 100        # the Newton chain ran, and agreed
    if scene == "particle" and h == 0.2:
        assert spec.stats["curvature_steps"] > 0


def test_negative_control_the_comparison_sees_a_last_bit_change(built, monkeypatch):
    gen = _run("skate", 0.1, 300, None, monkeypatch, compensated=False)
    spec = _run("skate", 0.1, 300, built, monkeypatch)
    d = np.max(np.abs(gen.q - spec.q))
    assert 0 < d < 1e-12                                   # a rounding difference only ...
    with pytest.raises(AssertionError):
        _same(gen, spec)                                   # ... and the check fails on it


def test_integrate_runs_it_when_ready_and_says_so(built, registry):
    registry._ready[KEY] = built
    a = ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=50, engine="compiled")
    assert a.stats["kernel_specialised"] is True
    registry.os.environ["LDASPARK_SPECIALISE"] = "0"
    b = ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=50, engine="compiled")
    assert b.stats["kernel_specialised"] is False
    assert np.array_equal(a.q, b.q) and np.array_equal(a.v, b.v)


def test_nothing_is_looked_up_before_load_after(registry, monkeypatch):
    calls = []
    monkeypatch.setattr(SP, "_load", lambda *k: calls.append(k))
    assert SP.kernel(*KEY) is None
    SP.note(*KEY, SP.LOAD_AFTER / 2)
    assert SP.kernel(*KEY) is None and calls == []
    SP.note(*KEY, SP.LOAD_AFTER)
    assert SP.kernel(*KEY) is None and calls == [KEY]     # looked once ...
    assert SP.kernel(*KEY) is None and calls == [KEY]     # ... not at every call


def test_a_build_is_started_once_after_build_after_and_its_result_loaded(registry, monkeypatch, built, tmp_path):
    marker = tmp_path / "built"
    monkeypatch.setattr(SP, "_command", lambda key: [sys.executable, "-c", f"open({str(marker)!r}, 'w').close()"])
    monkeypatch.setattr(SP, "_load", lambda *k: built if marker.exists() else None)
    SP.note(*KEY, SP.LOAD_AFTER)
    assert SP.kernel(*KEY) is None                         # not in the cache yet
    SP.note(*KEY, 0.0)
    assert SP.status(*KEY) == "not built"                  # below BUILD_AFTER: no build yet
    SP.note(*KEY, SP.BUILD_AFTER)
    t = SP._builds.get(KEY)
    assert t is not None and SP.status(*KEY) == "building"
    SP.note(*KEY, SP.BUILD_AFTER)                          # one build, not two
    assert SP._builds.get(KEY) is t
    t.join(60)
    assert marker.exists() and SP.status(*KEY) == "not built"
    assert SP.kernel(*KEY) is built and SP.status(*KEY) == "ready"


def test_a_failed_build_leaves_the_generic_kernel_and_is_not_retried(registry, monkeypatch):
    monkeypatch.setattr(SP, "_command", lambda key: [sys.executable, "-c", "import sys; sys.exit(3)"])
    monkeypatch.setattr(SP, "_load", lambda *k: None)
    SP.note(*KEY, SP.LOAD_AFTER)
    SP.kernel(*KEY)
    SP.note(*KEY, SP.BUILD_AFTER)
    SP._builds[KEY].join(60)
    deadline = time.monotonic() + 10
    while KEY in SP._builds and time.monotonic() < deadline:
        time.sleep(0.01)
    assert SP.status(*KEY) == "failed: build process exited 3: "
    SP.note(*KEY, SP.BUILD_AFTER)
    assert KEY not in SP._builds and SP.kernel(*KEY) is None
    r = ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=20, engine="compiled")
    assert r.stats["kernel_specialised"] is False


def test_the_source_carries_the_sizes_and_the_helpers_digest():
    from ldaspark.compiled import kernels_quasi
    src = SP.specialised_source(3, 4, 2)
    assert "S_, N_, M_ = 3, 4, 2" in src and kernels_quasi.HELPERS_SHA256 in src
    assert "@numba.njit" not in src and ".shape[0]" in src      # shapes off the step's path stay
    assert SP.specialised_source(3, 4, 2) != SP.specialised_source(3, 4, 1)
    for bad in ((0, 3, 1), (SP.MAX_S + 1, 3, 1), (2, SP.MAX_N + 1, 1), (2, 3, -1)):
        with pytest.raises(LdasparkError):
            SP.specialised_source(*bad)


def test_every_function_on_the_steps_path_reads_the_sizes_as_constants():
    """The step loop (``quasi_steps``), the residual, the matrices and the
    increments of the generated text take s, n, m from S_, N_, M_: a function whose size line the
    substitutions miss compiles with trip counts read from arrays (correct, only slower), so it is
    checked here by name. Negative control: the generic text reads them from the arrays."""
    import re
    from ldaspark.compiled import specialised as sp
    on_path = ("quasi_steps", "mech_residual", "stage_points", "multiplier_matrix",
               "quasi_increment", "curvature_matrix", "curvature_increment", "freeze_constraint")

    def size_lines(text, name):
        body = re.search(r"\ndef " + name + r"\(.*?(?=\n\n\n|\Z)", text, re.S).group(0)
        return [ln.strip() for ln in body.splitlines()
                if re.match(r"\s+(s, n, m|s, m, n|s, n|s|n|m) = ", ln) and ("shape" in ln or "_" in ln)]

    src = SP.specialised_source(5, 3, 2)
    generic = sp._read("kernels_quasi.py") + sp._read("kernels_mech.py") + sp._read("newton.py")
    for name in on_path:
        lines = size_lines(src, name)
        assert lines, name
        assert all("shape" not in ln for ln in lines), (name, lines)
        assert any("shape" in ln for ln in size_lines(generic, name)), name     # the control


@settings(max_examples=1, database=None, derandomize=True, deadline=None)
@given(case=mechanical_cases(n_range=(3, 3)))
def test_the_same_bits_on_a_drawn_mechanical_system(case):
    """The differential harness's mechanical draw (M non-diagonal, U quadratic + cubic, K(q) with a
    q-dependent entry, b(q) = beta sin(q_h) + rho != 0, t0 != 0; docs/verification.md): gauss-2
    on the specialised kernel of its sizes and on the generic one, every output bit for bit."""
    cs = runner.compile_system(case.system)
    ep = SP.build(2, cs.n, cs.m)
    out = []
    for e in (None, ep):
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(SP, "kernel", lambda *a, e=e: e)
            out.append(Q.run_quasi(cs, "gauss-2", case.t0, case.q0, case.v0, case.h, 40, 1))
    assert out[1].stats["kernel_specialised"] and not out[0].stats["kernel_specialised"]
    _same(*out)


@pytest.mark.exhaustive
@pytest.mark.parametrize("scene,method,h", (("robot", "gauss-3", 0.2), ("rolling-disk", "gauss-4", 0.5)))
def test_the_same_bits_on_other_sizes(monkeypatch, scene, method, h):
    sc = get_scene(scene)
    cs = runner.compile_system(sc.system)
    s = runner.kernel_spec(method, "spark")[1][1].shape[0]
    ep = SP.build(s, cs.n, cs.m)
    t0, q0, v0 = sc.initial()
    out = []
    for e in (None, ep):
        monkeypatch.setattr(SP, "kernel", lambda *a, e=e: e)
        out.append(Q.run_quasi(cs, method, t0, q0, v0, h, 300, 1))
    _same(*out)


def test_a_build_thread_inherited_through_fork_does_not_block_the_child(registry, monkeypatch, tmp_path):
    """After a fork the child holds the parent's thread object, not alive there: not 'building',
    and the child may start its own build."""
    import threading
    dead = threading.Thread(target=lambda: None)
    dead.start()
    dead.join()
    SP._builds[KEY] = dead
    SP._tried.add(KEY)
    SP._spent[KEY] = SP.BUILD_AFTER
    assert SP.status(*KEY) == "not built"
    marker = tmp_path / "built"
    monkeypatch.setattr(SP, "_command", lambda key: [sys.executable, "-c", f"open({str(marker)!r}, 'w').close()"])
    SP.note(*KEY, 0.0)
    t = SP._builds[KEY]
    assert t is not dead
    t.join(60)
    assert marker.exists()


def test_the_build_process_command_builds_or_says_why_in_one_line(built):
    """The command the background thread runs: it loads (or compiles) the kernel and exits 0;
    sizes out of range are one line on stderr and exit 2, no traceback."""
    import subprocess
    p = subprocess.run(SP._command(KEY), capture_output=True, text=True, timeout=600)
    assert p.returncode == 0 and p.stdout.startswith("built (2, 3, 1)"), p.stderr
    p = subprocess.run(SP._command((0, 3, 1)), capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert p.stderr.strip().splitlines() == [p.stderr.strip()] and "(0, 3, 1)" in p.stderr
