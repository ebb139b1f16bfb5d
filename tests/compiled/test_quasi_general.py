"""The quasi-Newton root finder for systems in the general form (``compiled.kernels_quasi_general``,
``run_quasi`` on a general model, ``integrate(..., engine="compiled", newton="quasi")``): the same
equations (21) as the compiled Newton engine, the velocity block frozen at L_vv at the predictor.

Tolerances: scenes as tests/compiled/test_kernels_quasi.py (both root finders stop within
lim = tol (|x| + |v0|) <= 8 eps scale of the root, so N steps differ by at most 2 N 8 eps scale);
random systems by ``verification.harness.agreement_tol`` (the same stopping bound amplified by
the condition number of the saddle matrix (4), which the drawn L_vv and k_v can make large).
"""
import hashlib
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, seed, settings

import ldaspark
from ldaspark.compiled.fast import compile_system, run_compiled
from ldaspark.compiled.quasi import run_quasi
from ldaspark.core.errors import InputError
from ldaspark.models.scenes import get_scene
from verification.harness import SEED, agreement_tol, saddle_cond
from verification.strategies import general_systems
from quasi_helpers import EPS, trajectory_difference as _difference

N, H = 200, 0.05

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def test_kernel_file_records_its_helpers():
    """numba keys the cached general_quasi_run on kernels_quasi_general.py only: HELPERS_SHA256 is
    the digest of the modules compiled into it."""
    from ldaspark.compiled import kernels_quasi_general as K
    d = os.path.dirname(K.__file__)
    h = hashlib.sha256()
    for f in K.HELPERS:
        with open(os.path.join(d, f), "rb") as fh:
            h.update(fh.read())
    assert K.HELPERS_SHA256 == h.hexdigest(), "update HELPERS_SHA256 in ldaspark/compiled/kernels_quasi_general.py"


@pytest.mark.parametrize("scene", ["relativistic", "chaplygin-sleigh", "constant-speed", "ball-turntable"])
def test_same_trajectory_as_newton_on_general_scenes(scene):
    """General-form scenes (a magnetic field: L_vq != 0; k nonlinear in v; n = 5, m = 2), gauss-2,
    gauss-3 and lobatto-iiia-iiib-3, 200 steps of h = 0.05: within the bound of the module
    docstring (measured at most 0.034 of it), every step counted as a quasi step or a fallback.
    Negative control: another method of the same order breaks the bound."""
    sc = get_scene(scene)
    t0, q0, v0 = sc.initial()
    cs = compile_system(sc.system)
    assert cs.form == "general"
    for fam in ("gauss-2", "gauss-3", "lobatto-iiia-iiib-3"):
        a = run_compiled(cs, fam, t0, q0, v0, H, N, 1, kernel="spark")
        b = run_quasi(cs, fam, t0, q0, v0, H, N, 1)
        st = b.stats
        assert st["steps"] == N and st["quasi_steps"] + st["quasi_fallbacks"] == N and st["quasi_steps"] > 0
        assert st["form"] == "general" and st["root_finder"] == "quasi" and st["curvature_steps"] == 0
        assert _difference(a, b) <= 1.0, (scene, fam, _difference(a, b))
    other = run_compiled(cs, "lobatto-iiia-iiib-2", t0, q0, v0, H, N, 1, kernel="spark")
    assert _difference(other, run_quasi(cs, "gauss-2", t0, q0, v0, H, N, 1)) > 1.0


@seed(SEED)
@settings(max_examples=6, deadline=None, database=None, suppress_health_check=list(HealthCheck))
@given(case=general_systems(n_range=(2, 3), m_max=2, dps=30))
def test_random_general_systems_agree_with_newton(case):
    """Random general systems of the differential harness's family (L with explicit t, L_qv != 0,
    L not quadratic in v, k nonlinear in v with b != 0), gauss-2 and gauss-3, 8 steps of h = 1/16
    from the drawn point: quasi-Newton and Newton within ``agreement_tol`` (8 steps, the saddle
    matrix's condition number at the start, the run's scale)."""
    cs = compile_system(case.system)
    t0, q0, v0 = float(case.t0), [float(x) for x in case.q0], [float(x) for x in case.v0]
    cond = saddle_cond(case.system, t0, q0, v0, {})
    for fam in ("gauss-2", "gauss-3"):
        a = run_compiled(cs, fam, t0, q0, v0, 1 / 16, 8, 1, kernel="spark")
        b = run_quasi(cs, fam, t0, q0, v0, 1 / 16, 8, 1)
        scale = max(1.0, float(np.abs(a.q).max()), float(np.abs(a.v).max()))
        d = max(float(np.abs(a.q - b.q).max()), float(np.abs(a.v - b.v).max()))
        assert d <= agreement_tol(8, cond, scale), (case, fam, d)
        assert b.stats["quasi_steps"] + b.stats["quasi_fallbacks"] == 8


def test_integrate_general_form_and_nonideal_refused():
    """Through ldaspark.integrate: the relativistic particle (general form) runs with newton="quasi"
    and agrees with the default compiled Newton; the friction skate (a nonideal term N, section
    3.3) is refused by name, as is the generic engine."""
    a = ldaspark.integrate("relativistic", "gauss-2", h=0.05, n_steps=100, engine="compiled")
    b = ldaspark.integrate("relativistic", "gauss-2", h=0.05, n_steps=100, engine="compiled", newton="quasi")
    assert b.stats["root_finder"]["kind"] == "quasi" and b.stats["quasi_steps"] + b.stats["quasi_fallbacks"] == 100
    assert _difference(a, b) <= 1.0
    with pytest.raises(InputError, match="nonideal"):
        ldaspark.integrate("friction-skate", "gauss-2", h=0.05, n_steps=3, engine="compiled", newton="quasi")
    with pytest.raises(InputError, match="quasi"):
        ldaspark.integrate("relativistic", "gauss-2", h=0.05, n_steps=3, engine="generic", newton="quasi")


@pytest.mark.parametrize("fam,s", [("gauss-2", 2), ("lobatto-iiia-iiib-3", 3)])
def test_nlu_counts_the_frozen_velocity_blocks(fam, s):
    """A general-form quasi-Newton attempt factors s + 1 matrices L_vv (the stages and the end
    point) and the multiplier matrix S: s + 2 LU factorisations, all of them in ``nlu`` (its one
    meaning on every engine, ``Result``). Before: nlu = multiplier_lu, 1 a step (relativistic,
    gauss-2, 10 steps: nlu 10 for 40 factorisations). Exact counts: no step fell back here, so
    the Newton chain factored nothing. Control: the mechanical form without curvature (the skate,
    Hess U = 0) factors only S per step (M is factored once per run, outside the step) and keeps
    nlu = multiplier_lu."""
    g = ldaspark.integrate("relativistic", fam, h=0.05, n_steps=10, engine="compiled", newton="quasi")
    st = g.stats
    assert st["quasi_fallbacks"] == 0 and st["multiplier_lu"] == 10, st
    assert g.nlu == st["nlu"] == (s + 2) * st["multiplier_lu"], st
    m = ldaspark.integrate("skate", fam, h=0.05, n_steps=10, engine="compiled", newton="quasi")
    assert m.stats["quasi_fallbacks"] == 0 and m.stats["curvature_refreshes"] == 0, m.stats
    assert m.nlu == m.stats["multiplier_lu"] == 10, m.stats
