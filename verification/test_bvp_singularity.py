"""Why the boundary-value solve of Theorem 1 is singular for some method/scene pairs.

Mechanism (measured in reports/claims.md, explained here): when the constraint is holonomic along
the step, k = d/dt g(q) with g quadratic (the printed 8.4 scene: g = q1 + sum_{i>=5} q_i^2/2), and
the stages come from Gauss collocation, the first row of (21e) (omega_1j = b_j) is

    sum_j b_j g_q(Q_j) V_j = (g(q1) - g(q0)) / h      for ANY stage velocities V,

because g_q(u) u' is a polynomial of degree 2s - 1 in t, integrated exactly by the Gauss weights.
With (21c) imposed, that row depends on the data (q0, q1) alone, so the Jacobian of the
boundary-value system has a dependent row: it is solvable only on the discrete constraint manifold
g(q1) = g(q0). The nonholonomic variant has no such g, and its solve is well-posed.
"""
import numpy as np
import pytest

from ldaspark.models.scenes import mp_particles
from ldaspark.core.families import gauss

RNG = np.random.default_rng(7)


def first_21e_row_and_discrete_g(scene, s, h=0.1):
    """(21e) row 1 for random stage velocities, and (g(q1) - g(q0))/h with q1 from (21c)."""
    sysm = scene.system
    tab = gauss(s).arrays(None)
    q0 = RNG.normal(size=sysm.n)
    V = RNG.normal(size=(s, sysm.n))
    Q = q0 + h * tab.A.dot(V)
    q1 = q0 + h * tab.b.dot(V)
    from ldaspark.core.backend import Backend
    bk = Backend(None)
    row = sum(tab.omega[0, j] * sysm.constraint(bk, 0.0, Q[j], V[j])[0] for j in range(s))
    g = lambda q: q[0] + 0.5 * np.sum(q[4:] ** 2)
    return row, (g(q1) - g(q0)) / h


@pytest.mark.parametrize("s", [2, 3])
def test_first_21e_row_is_data_only_on_the_printed_8_4_scene(s):
    row, dg = first_21e_row_and_discrete_g(mp_particles(), s)
    assert abs(row - dg) < 1e-12 * (1 + abs(dg))


@pytest.mark.parametrize("s", [2, 3])
def test_not_on_the_nonholonomic_variant(s):
    row, dg = first_21e_row_and_discrete_g(mp_particles(constraint="nonholonomic"), s)
    assert abs(row - dg) > 1e-3
