"""Every engine returns the stage multipliers Psi_i of (21): the compiled kernels as the generic
engine does (same steps, same shapes under save_every, chunked calls, dense output and events),
and their sign is that of (1), d/dt grad_v L = grad_q L - K^T psi, the negative of sympy's
LagrangesMethod multipliers."""
import numpy as np
import pytest
import sympy as sp

import ldaspark

# The engines solve the same step equations to the Newton tolerance (8 eps of the stage values),
# and Psi = Lambda / h carries that error divided by h times cond of the Newton matrix: measured
# differences are 2e-15..2e-14 at |psi| ~ 2, h = 0.1; 1e-11 (1 + |psi|) leaves three digits of room
# and still fails any real disagreement (a wrong stage, step or sign moves psi by O(|psi|)).
TOL = 1e-11


def _close(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    assert a.shape == b.shape, (a.shape, b.shape)
    return np.abs(a - b).max() <= TOL * (1 + np.abs(b).max())


@pytest.mark.parametrize("scene, method", [("skate", "gauss-2"), ("robot", "lobatto-iiia-iiib-3"),
                                           ("relativistic", "gauss-2"), ("mp-particles-nh", "gauss-3")])
@pytest.mark.parametrize("every", [1, 3])
def test_compiled_psi_equals_generic_psi(scene, method, every):
    kw = dict(t_span=(0, 1), h=0.1, save_every=every)
    gen = ldaspark.integrate(scene, method, engine="generic", **kw)
    com = ldaspark.integrate(scene, method, engine="compiled", **kw)
    assert com.engine == "compiled" and com.psi is not None
    assert com.psi.shape == (len(com.t) - 1, gen.psi.shape[1], gen.psi.shape[2])
    assert _close(com.psi, gen.psi)
    # negative control: the psi of the neighbouring step is another number
    assert not _close(com.psi[1:], gen.psi[:-1])


@pytest.mark.parametrize("every", [1, 6])
def test_chunked_runs_keep_the_psi_of_their_saved_steps(monkeypatch, every):
    kw = dict(t_span=(0, 2.4), h=0.1, save_every=every, engine="compiled")
    whole = ldaspark.integrate("skate", "gauss-2", **kw)
    monkeypatch.setattr("ldaspark.core.chunks.COMPILED_CHUNK", 4)      # every = 6 > the chunk: one sample per chunks
    parts = ldaspark.integrate("skate", "gauss-2", **kw)
    assert np.abs(parts.t - whole.t).max() <= 1e-14      # t0 + done h + j h against t0 + step h: rounding
    assert _close(parts.psi, whole.psi)


def test_dense_output_and_events_keep_psi():
    kw = dict(t_span=(0, 2), h=0.1, save_every=2, engine="compiled")
    plain = ldaspark.integrate("skate", "gauss-2", **kw)
    dense = ldaspark.integrate("skate", "gauss-2", dense_output=True, **kw)
    assert _close(dense.psi, plain.psi)

    def crossing(t, q, v):
        return q[0] + 0.3
    crossing.terminal = True
    hit = ldaspark.integrate("skate", "gauss-2", t_span=(0, 10), h=0.05, events=crossing, engine="compiled")
    assert hit.status == 1 and hit.psi.shape[0] == len(hit.t) - 1


def test_psi_sign_is_that_of_1_and_opposite_to_sympys_multiplier():
    me = pytest.importorskip("sympy.physics.mechanics")
    x, y, th = me.dynamicsymbols("x y theta")
    xd, yd, thd = me.dynamicsymbols("x y theta", 1)
    lm = me.LagrangesMethod((xd ** 2 + yd ** 2) / 2 + thd ** 2 / 2 - x, [x, y, th],
                            nonhol_coneqs=[sp.sin(th) * xd - sp.cos(th) * yd])
    lm.form_lagranges_equations()
    state = {x: 0, y: 0, th: 0.3, xd: np.cos(0.3), yd: np.sin(0.3), thd: 1.0}
    lam = float(lm.rhs()[-1].subs(state))                # sympy's multiplier at t = 0
    system = ldaspark.LagrangianSystem.from_mechanics(lm, name="skate-lagrange")
    for engine in ("generic", "compiled"):
        res = ldaspark.integrate(system, "gauss-2", t_span=(0, 1e-4), h=1e-4, q0=[0, 0, 0.3],
                                 v0=[np.cos(0.3), np.sin(0.3), 1.0], engine=engine)
        # the stages sit at t = c_i h = O(1e-4): psi(t) = psi(0) + O(|psi'| h) with |psi'| ~ 1
        assert abs(res.psi[0, 0, 0] + lam) < 1e-3 * (1 + abs(lam)), (engine, res.psi[0], lam)
        assert abs(res.psi[0, 0, 0] - lam) > abs(lam)     # control: the other sign is far off


def test_ensembles_return_psi_per_member():
    q0 = [[0, 0, 0], [0.1, 0, 0]]
    v0 = [[0.5, 0, 1], [0.5, 0, 0.5]]
    kw = dict(t_span=(0, 1), h=0.1, save_every=2)
    ens = ldaspark.integrate("skate", "gauss-2", q0=q0, v0=v0, **kw)
    assert ens.psi.shape == (2, np.shape(ens.t)[-1] - 1, 2, 1)
    for j in range(2):
        one = ldaspark.integrate("skate", "gauss-2", q0=q0[j], v0=v0[j], engine="generic", **kw)
        assert _close(ens.psi[j], one.psi)
    assert not _close(ens.psi[0], ens.psi[1])           # control: the members differ



@pytest.mark.parametrize("every", [1, 3])
@pytest.mark.parametrize("form", ["lobatto-iiia-iiib-2-leapfrog", "lobatto-iiia-iiib-2-modified"])
def test_a_comparator_s_psi_is_that_of_the_spark_method_it_rewrites(form, every):
    """The leapfrog form of (25) and the modified Lobatto method of 8.4 on the comparator engine
    (``integrate_comparator``) against lobatto-iiia-iiib-2 on the generic SPARK engine, on a
    mechanical system where they are the same step: the same Psi_1, Psi_2 (measured 2e-15). The
    comparator engine's psi was never compared with another path: returned as None, every test
    still passed. (The compiled comparator kernels return no psi, docs/changelog.md.)"""
    kw = dict(t_span=(0, 1), h=0.1, save_every=every, engine="generic")
    spark = ldaspark.integrate("skate", "lobatto-iiia-iiib-2", **kw)
    comp = ldaspark.integrate("skate", form, **kw)
    assert comp.stats["engine"] == "comparator" and comp.psi is not None
    assert _close(comp.psi, spark.psi)
    assert not _close(comp.psi[1:], spark.psi[:-1])          # control: the neighbouring step's psi
