"""Wrong types and values at the API give LdasparkError subclasses with clear messages, before
any work is done (never TypeError, AttributeError, UnboundLocalError or MemoryError)."""
import numpy as np
import pytest
import sympy

from ldaspark.core.errors import InputError, LdasparkError, SystemDefinitionError, SingularSaddleError, TableauError
from ldaspark.core.families import gauss, get_method, lobatto_iiia_iiib
from ldaspark.models.scenes import get_scene
from ldaspark.core.spark import SparkMethod, integrate
from ldaspark.core.system import LagrangianSystem
from ldaspark.core.validate import check_newton_options, check_storage


@pytest.fixture(scope="module")
def skate():
    return get_scene("skate")


@pytest.mark.parametrize("s", [2.5, "2", None, True, [2]])
def test_family_stage_count_types(s):
    with pytest.raises(TableauError, match="s must be an integer"):
        gauss(s)
    with pytest.raises(TableauError, match="s must be an integer"):
        lobatto_iiia_iiib(s)


def test_family_accepts_numpy_integers():
    assert gauss(np.int64(2)).s == 2                       # control


@pytest.mark.parametrize("name", [None, 2, b"gauss-2", ["gauss-2"]])
def test_get_method_name_types(name):
    with pytest.raises(TableauError, match="method name must be a string"):
        get_method(name)


def _qv():
    return list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))


@pytest.mark.parametrize("L, k, match", [
    (None, "v3", "must be sympy expressions"),
    ("v1**2", None, "must be sympy expressions"),
    (sympy.Matrix([1, 2]), ["v3"], "scalar expression"),
    (object(), ["v3"], "must be sympy expressions"),
    ("v1**2 +", ["v3"], "must be sympy expressions"),
])
def test_system_definition_types(L, k, match):
    q, v = _qv()
    with pytest.raises(SystemDefinitionError, match=match):
        LagrangianSystem(L, k, q, v)


def test_zero_mass_is_a_setup_error():
    sysm = LagrangianSystem.mechanical_form(sympy.diag(0, 1, 1), 0, [[0, 0, 1]])
    with pytest.raises(SingularSaddleError, match="assumption \\(4\\) fails"):
        integrate(sysm, get_method("gauss-2"), 0, [0, 0, 0], [1, 0, 0], 0.1, n_steps=2)


@pytest.mark.parametrize("kw, match", [
    (dict(tol=0), "tolerance must be a finite positive"), (dict(tol=float("nan")), "tolerance"),
    (dict(tol=-1e-3), "tolerance"), (dict(tol="1e-10"), "tolerance"), (dict(tol=float("inf")), "tolerance"),
    (dict(max_iter=0), "max_iter must be an integer"), (dict(max_iter=2.5), "max_iter"),
    (dict(max_iter=True), "max_iter"), (dict(max_iter=None), "max_iter"),
])
def test_newton_options(skate, kw, match):
    with pytest.raises(InputError, match=match):
        SparkMethod(skate.system, get_method("gauss-2"), **kw)
    with pytest.raises(InputError, match=match):
        check_newton_options(kw.get("tol"), kw.get("max_iter", 50))


def test_integrate_tol_is_checked_before_newton(skate):
    t0, q0, v0 = skate.initial()
    for tol in (0, float("nan")):
        with pytest.raises(InputError, match="tolerance"):     # not 'Newton did not converge'
            integrate(skate.system, get_method("gauss-2"), t0, q0, v0, 0.1, n_steps=2, tol=tol)


@pytest.mark.parametrize("system, tableau, match", [
    (None, "gauss-2", "system must be a LagrangianSystem"),
    ("skate", "gauss-2", "system must be a LagrangianSystem"),
    ("SYSTEM", None, "tableau must be a SparkTableau"),
    ("SYSTEM", "gauss-2", "tableau must be a SparkTableau"),
])
def test_integrate_argument_types(skate, system, tableau, match):
    system = skate.system if system == "SYSTEM" else system
    with pytest.raises(InputError, match=match):
        integrate(system, tableau, 0, [0, 0, 0], [0, 0, 1], 0.1, n_steps=2)


def test_billion_steps_is_refused_before_allocating(skate):
    # before: a raw MemoryError (or swapping) building the time grid
    t0, q0, v0 = skate.initial()
    with pytest.raises(InputError, match="GiB"):
        integrate(skate.system, get_method("gauss-2"), t0, q0, v0, 1e-9, n_steps=10 ** 9)


def test_storage_check_has_teeth():
    check_storage(10 ** 4, 10)                               # control: 4 MB is fine
    with pytest.raises(InputError, match="GiB"):
        check_storage(10 ** 12, 10)


def test_all_new_errors_are_ldaspark_errors():
    from ldaspark.core import errors
    assert issubclass(errors.NonFiniteError, LdasparkError)


@pytest.mark.parametrize("kw, match", [(dict(max_iter=0), "max_iter"), (dict(tol=0.0), "tolerance"),
                                       (dict(tol=float("nan")), "tolerance"), (dict(n_steps=10 ** 9), "GiB"),
                                       (dict(n_steps=10 ** 12), r"between 1 and 1e\+09"),   # a run that cannot end
                                       (dict(h=True), "bool")])
def test_fast_path_options_are_input_errors(skate, kw, match):
    # before: UnboundLocalError (max_iter=0), 'Newton failed' (tol=0 / nan), MemoryError or a hang
    from ldaspark.compiled.fast import fast_integrate
    args = dict(h=0.1, n_steps=10)
    args.update(kw)
    with pytest.raises(InputError, match=match):
        fast_integrate(skate, "gauss-2", **args)
