"""The block-sparse Newton linear algebra of the compiled SPARK kernel (``compiled.sparse``,
``compiled.kernels_sparse``, ``run_compiled(linear_solver=...)``).

Checked three ways: the symbolic structure (the filled pattern is closed under elimination and
holds the matrix's pattern; minimum degree creates no fill on a path), the assembled matrix and
the solve against the dense Newton matrix of ``kernels_mech.spark_jacobian`` at the same point
(entry by entry, and the increment against numpy's solve), and whole runs against the dense LU
(same iterates up to the rounding of the linear solves)."""
import numpy as np
import pytest
import sympy

from ldaspark.compiled import fast, runner, sparse
from ldaspark.compiled.fast import compile_system, run_compiled
from ldaspark.core.errors import InputError, NewtonError
from ldaspark.models.scenes import Scene, get_scene, mp_particles
from ldaspark.core.system import LagrangianSystem


def _closed(st):
    """Row r holds every column d > c of each row c < r it couples to (no fill is missing)."""
    rows = [set(st.col_pos[st.row_ptr[r]:st.row_ptr[r + 1]].tolist()) for r in range(len(st.perm))]
    for r, row in enumerate(rows):
        for c in [c for c in row if c < r]:
            if not {d for d in rows[c] if d > c} <= row:
                return False
    return True


def test_minimum_degree_on_a_path_creates_no_fill_and_the_pattern_is_kept():
    n = 9
    pairs = [(i, i + 1) for i in range(n - 1)]
    st = sparse.newton_structure(n, pairs, np.eye(n))
    assert st.fill_ratio == 1.0 and st.n_blocks == n + 2 * (n - 1) and _closed(st)
    # every entry of P sits in the slot of its (position, position)
    for a in range(n):
        for e in range(st.pattern_ptr[a], st.pattern_ptr[a + 1]):
            r, c = st.perm[a], st.perm[st.pattern_col[e]]
            assert st.col_pos[st.pattern_slot[e]] == c and st.row_ptr[r] <= st.pattern_slot[e] < st.row_ptr[r + 1]


def test_minimum_degree_on_a_star_eliminates_the_leaves_first():
    """A hub coupled to every other degree of freedom (one coordinate in every constraint or
    potential term): eliminating the hub first fills the whole matrix, the leaves first none."""
    n = 12
    st = sparse.newton_structure(n, [(0, j) for j in range(1, n)], np.eye(n))
    assert st.fill_ratio == 1.0 and st.perm[0] >= n - 2     # (with the last leaf, a tie)


@pytest.mark.parametrize("seed", range(6))
def test_filled_pattern_is_closed_for_random_patterns(seed):
    rng = np.random.default_rng(seed)
    n = 30
    pairs = [tuple(p) for p in rng.integers(0, n, size=(40, 2))]
    st = sparse.newton_structure(n, pairs, np.eye(n))
    assert _closed(st) and sorted(st.perm.tolist()) == list(range(n))
    assert st.block_updates >= 0 and st.fill_ratio >= 1.0


def test_budget_bounds_the_fill_not_n():
    """A chain of n = 3000 couplings (no fill) gets its structure: the budget counts the cliques
    the elimination forms, not the choice of the next node (a scan of the remaining nodes,
    n^2 / 2 = 4.5e6, exceeded it by itself)."""
    n = 3000
    st = sparse.newton_structure(n, [(i, i + 1) for i in range(n - 1)], np.eye(n))
    assert st is not None and st.fill_ratio == 1.0 and st.n_blocks == 3 * n - 2


def test_dense_pattern_exceeds_the_symbolic_budget():
    n = 40
    pairs = [(i, j) for i in range(n) for j in range(n)]
    assert sparse.newton_structure(n, pairs, np.eye(n), budget=10_000) is None
    assert sparse.newton_structure(n, pairs, np.eye(n)) is not None


def _coupled(n=6):
    """A mechanical system whose M is not diagonal (tridiagonal SPD), whose U couples neighbours,
    with two constraints k = K(q) v + b(t, q): every block of the saddle matrix is exercised."""
    q = sympy.symbols(f"q0:{n}")
    v = sympy.symbols(f"v0:{n}")
    t = sympy.Symbol("t")
    M = sympy.zeros(n, n)
    for i in range(n):
        M[i, i] = 2 + sympy.Rational(i, 5)
        if i + 1 < n:
            M[i, i + 1] = M[i + 1, i] = sympy.Rational(1, 3)
    U = sum(q[i] ** 2 / 2 + q[i] ** 2 * q[(i + 1) % n] ** 2 / 4 for i in range(n)) + sympy.cos(q[0] * q[3])
    K = sympy.Matrix([[1, 0, -q[1], 0, 0, 0], [0, sympy.sin(q[2]), 0, 1, -q[4], 0]])[:, :n]
    b = sympy.Matrix([0, sympy.sin(t) / 10])
    vv = sympy.Matrix(v)
    L = (vv.T * M * vv)[0] / 2 - U
    k = list(K * vv + b)
    sysm = LagrangianSystem(L, k, list(q), list(v), t=t, name="coupled-6", mechanical=None)
    sysm.mechanical = {"M": M, "U": U, "K": K, "b": b}
    q0 = [sympy.Rational(i + 1, 10) for i in range(n)]
    v0 = [0] * n
    v0[1] = sympy.Rational(1, 2)
    v0[2] = 1
    v0[0] = q0[1] * v0[2]                               # k1 = 0 at t = 0
    v0[3] = q0[4] * v0[4] - sympy.sin(q0[2]) * v0[1]     # k2 = 0 at t = 0 (b(0) = 0)
    return Scene("coupled-6", sysm, sympy.Integer(0), q0, v0, "coupled mechanical test system")


def _initial(sc):
    t0, q0, v0 = sc.initial()
    return float(t0), np.array([float(x) for x in q0]), np.array([float(x) for x in v0])


@pytest.mark.parametrize("method", ["gauss-1", "gauss-2", "gauss-3", "lobatto-iiia-iiib-3",
                                    "lobatto-iiia-iiib-iiid-2", "lobatto-iiia-iiib-iiid-3"])
def test_assembled_matrix_and_solve_equal_the_dense_ones(method):
    """At the predictor point of a step of the coupled system: the blocks, B and C equal the dense
    Newton matrix entry by entry (to 1e-15 relative: the same products, summed in another order),
    and the sparse increment equals numpy's solve of the dense system to 1e-12 relative."""
    from ldaspark.compiled import kernels, kernels_mech
    sc = _coupled()
    cs = compile_system(sc.system)
    t0, q0, v0 = _initial(sc)
    spec = fast.kernel_spec(method, "spark")[1]
    s, n, m = spec[1].shape[0], cs.n, cs.m
    st = sparse.newton_structure(n, cs.hess_pattern, cs.M)
    NN = s * (n + m) + n
    x = np.random.default_rng(1).normal(scale=1e-2, size=NN)
    h = 0.05
    ws = kernels_mech.mech_workspace(s, n, m, cs.M)
    G, J = np.zeros(NN), np.zeros((NN, NN))
    kernels_mech.spark_eval(cs.model, spec, True, x, t0, q0, v0, h, cs.M, ws, G, J)
    ws2 = kernels_mech.mech_workspace(s, n, m, cs.M)
    sp = kernels.sparse_workspace(s, m, *st.arrays())
    G2 = np.zeros(NN)
    kernels_mech.spark_eval_sparse(cs.model, spec, True, x, t0, q0, v0, h, cs.M, ws2, G2, sp)
    assert np.array_equal(G, G2)
    # expand the blocks to the dense layout: y (s + 1) perm[a] + i <-> x i n + a (Z), s n + s m + a (dv)
    b = s + 1
    xcol = lambda a, i: i * n + a if i < s else s * n + s * m + a    # noqa: E731
    xrow = lambda a, i: i * n + a if i < s else s * n + a            # noqa: E731
    iperm = np.argsort(st.perm)
    D = np.zeros((NN, NN))
    val, B, C = sp[7], sp[9], sp[10]
    for r in range(n):
        for e in range(st.row_ptr[r], st.row_ptr[r + 1]):
            c = st.col_pos[e]
            for i in range(b):
                for k in range(b):
                    D[xrow(iperm[r], i), xcol(iperm[c], k)] = val[e, i, k]
    for a in range(n):
        for i in range(b):
            D[xrow(a, i), s * n:s * n + s * m] = B[st.perm[a] * b + i]
            D[s * n + n:, xcol(a, i)] = C[:, st.perm[a] * b + i]
    scale = np.abs(J).max()
    assert np.abs(D - J).max() <= 1e-15 * scale
    stats = np.zeros(len(fast.STAT_NAMES), dtype=np.int64)
    from ldaspark.compiled.kernels_sparse import sparse_factor, sparse_increment
    assert sparse_factor(stats, G2, sp) == 1
    x2 = x.copy()
    sparse_increment(sp, G2, x2)
    dx = np.linalg.solve(J, -G)
    assert np.abs((x2 - x) - dx).max() <= 1e-12 * np.abs(dx).max()


@pytest.mark.parametrize("scene,method,h,steps", [
    ("coupled", "gauss-2", 0.02, 200), ("coupled", "gauss-4", 0.05, 100),
    ("coupled", "lobatto-iiia-iiib-iiid-3", 0.02, 200), ("coupled", "euler-ii", 0.01, 200),
    ("mp-particles", "gauss-3", 0.01, 200), ("mp-particles-nh", "gauss-2", 0.02, 300),
    ("robot", "gauss-2", 0.05, 200), ("skate", "gauss-3", 0.05, 200), ("particle", "gauss-1", 0.02, 200)])
def test_runs_agree_with_the_dense_lu(scene, method, h, steps):
    """Whole runs: the same samples as the dense LU to 1e-12 (relative to max(1, |x|)), the same
    Newton work (iterations, Jacobians, one LU per Jacobian), stats naming the solver."""
    sc = _coupled() if scene == "coupled" else get_scene(scene)
    cs = compile_system(sc.system)
    t0, q0, v0 = _initial(sc)
    a = run_compiled(cs, method, t0, q0, v0, h, steps, kernel="spark", linear_solver="dense")
    b = run_compiled(cs, method, t0, q0, v0, h, steps, kernel="spark", linear_solver="sparse")
    assert a.stats["linear_solver"] == "dense" and b.stats["linear_solver"] == "sparse"
    for k in ("q", "v", "energy", "constraint"):
        ref = np.asarray(getattr(a, k))
        assert np.abs(np.asarray(getattr(b, k)) - ref).max() <= 1e-12 * max(1.0, np.abs(ref).max()), k
    # the same work up to a stopping decision flipped by rounding (the two solves round differently)
    assert abs(a.stats["newton_iterations"] - b.stats["newton_iterations"]) <= 0.02 * steps
    assert abs(a.stats["njev"] - b.stats["njev"]) <= 0.02 * steps
    assert a.stats["full_newton_steps"] == b.stats["full_newton_steps"] == 0
    # every Newton matrix assembled is factored once (none is non-finite or singular on these
    # runs): nlu = njev on both solvers, as ``newton.factor_newton`` and ``kernels_sparse.sparse_factor`` count
    assert a.stats["nlu"] == a.stats["njev"] >= 1 and b.stats["nlu"] == b.stats["njev"], (a.stats, b.stats)


def test_auto_picks_by_operation_count():
    """auto: the dense LU for the skate (n = 3: the block code's bookkeeping costs more than it
    saves), the block LU for the particles at n = 41 (dense ~1e6 multiply-adds per factorisation,
    blocks ~1e4)."""
    small = get_scene("skate")
    cs = compile_system(small.system)
    assert run_compiled(cs, "gauss-2", *_initial(small), 0.1, 3).stats["linear_solver"] == "dense"
    big = mp_particles(m=20, constraint="nonholonomic")
    cb = compile_system(big.system)
    st = cb.newton_structure()
    assert fast.SPARSE_MARGIN * st.factor_flops(2, 1) < sparse.dense_flops(2, 41, 1)
    assert run_compiled(cb, "gauss-2", *_initial(big), 0.01, 3).stats["linear_solver"] == "sparse"


def _indefinite():
    """L = v1 v2 - U: M = [[0, 1], [1, 0]] is nonsingular but has a zero diagonal, so with U free
    of the coupling the diagonal blocks of the block LU vanish to O(h^2): the block order has no
    usable pivot while the dense LU (pivoting across blocks) has."""
    q = sympy.symbols("q0:2")
    v = sympy.symbols("v0:2")
    L = v[0] * v[1] - (q[0] ** 4 + q[1] ** 4) / 4
    k = [v[0] - q[1] * v[1] / 10]
    sysm = LagrangianSystem(L, k, list(q), list(v), name="indefinite")
    return Scene("indefinite", sysm, sympy.Integer(0), [0, 0], [sympy.Rational(1, 10), 1], "zero-diagonal M")


def test_small_block_pivot_falls_back_to_the_dense_lu(monkeypatch):
    """Forced: the block LU reports a singular matrix; auto (made to choose the blocks even at
    n = 2) repeats the run with the dense LU and returns its result."""
    monkeypatch.setattr(runner, "SPARSE_MARGIN", 0.0)
    sc = _indefinite()
    cs = compile_system(sc.system)
    assert cs.form == "mechanical"
    t0, q0, v0 = _initial(sc)
    with pytest.raises(NewtonError, match="singular"):
        run_compiled(cs, "gauss-2", t0, q0, v0, 0.01, 20, kernel="spark", linear_solver="sparse")
    d = run_compiled(cs, "gauss-2", t0, q0, v0, 0.01, 20, kernel="spark", linear_solver="dense")
    a = run_compiled(cs, "gauss-2", t0, q0, v0, 0.01, 20, kernel="spark", linear_solver="auto")
    assert a.stats["linear_solver"] == "dense" and np.array_equal(a.q, d.q)
    # the block LU's failed attempt is work done: counted beside the dense run's (it was zeroed)
    assert a.stats["nlu"] > d.stats["nlu"] and a.stats["njev"] > d.stats["njev"], (a.stats, d.stats)
    assert a.stats["steps"] == d.stats["steps"]


def test_linear_solver_option_is_checked():
    sc = get_scene("constant-speed")
    cs = compile_system(sc.system)
    t0, q0, v0 = _initial(sc)
    with pytest.raises(InputError, match="mechanical form"):
        run_compiled(cs, "gauss-2", t0, q0, v0, 0.01, 2, linear_solver="sparse")
    with pytest.raises(InputError, match="linear_solver"):
        run_compiled(cs, "gauss-2", t0, q0, v0, 0.01, 2, linear_solver="lu")


def _random_mechanical(seed, n, m=2):
    """A random mechanical system: M SPD with a random sparse pattern, U a sum of random quartic
    couplings and cosines of random pairs, k = K(q) v + b(t, q) with K rows that touch a few
    coordinates and depend on q; initial velocity projected onto k = 0 at t = 0."""
    rng = np.random.default_rng(seed)
    q = sympy.symbols(f"q0:{n}")
    v = sympy.symbols(f"v0:{n}")
    t = sympy.Symbol("t")
    R = lambda x: sympy.Rational(int(round(x * 100)), 100)   # noqa: E731
    M = sympy.zeros(n, n)
    for i in range(n):
        M[i, i] = 2 + R(rng.uniform(0, 1))
    for _ in range(n // 2):
        i, j = rng.choice(n, 2, replace=False)
        M[i, j] = M[j, i] = R(rng.uniform(-0.4, 0.4))
    U = sum(q[i] ** 2 / 2 for i in range(n))
    for _ in range(n):
        i, j = rng.choice(n, 2, replace=False)
        U += R(rng.uniform(0.1, 0.5)) * q[i] ** 2 * q[j] ** 2 + R(rng.uniform(0, 0.3)) * sympy.cos(q[i] - q[j])
    K = sympy.zeros(m, n)
    picks = rng.choice(n, 3 * m, replace=False)          # disjoint columns: K has full rank m
    for l in range(m):
        cols = picks[3 * l:3 * l + 3]
        K[l, cols[0]] = 1
        K[l, cols[1]] = q[int(cols[2])] / 2
        K[l, cols[2]] = sympy.sin(q[int(cols[1])]) / 3
    b = sympy.Matrix([sympy.sin(t) * q[int(rng.integers(n))] / 10 for _ in range(m)])
    vv = sympy.Matrix(v)
    L = (vv.T * M * vv)[0] / 2 - U
    sysm = LagrangianSystem(L, list(K * vv + b), list(q), list(v), t=t, name=f"random-mech-{seed}")
    sysm.mechanical = {"M": M, "U": U, "K": K, "b": b}
    q0 = np.array([float(x) for x in rng.uniform(-0.5, 0.5, n)])
    Kq = np.array(K.subs(dict(zip(q, q0))), dtype=float)
    w = rng.uniform(-1, 1, n)
    v0 = w - Kq.T @ np.linalg.solve(Kq @ Kq.T, Kq @ w)       # K(q0) v0 = 0 = -b(0, q0)
    return sysm, q0, v0


@pytest.mark.parametrize("seed,n,method", [(0, 9, "gauss-2"), (1, 14, "gauss-3"),
                                           pytest.param(2, 20, "gauss-4", marks=pytest.mark.exhaustive),
                                           pytest.param(3, 12, "lobatto-iiia-iiib-iiid-3",
                                                        marks=pytest.mark.exhaustive),
                                           pytest.param(4, 30, "gauss-2", marks=pytest.mark.exhaustive),
                                           pytest.param(5, 8, "lobatto-iiia-iiib-3", marks=pytest.mark.exhaustive)])
def test_random_mechanical_systems_agree_with_the_dense_lu(seed, n, method):
    """Systems the suite's authors did not write: random patterns of M, Hess U and K (so random
    fill), two constraints; 100 steps of h = 0.02 agree with the dense LU to 1e-12."""
    sysm, q0, v0 = _random_mechanical(seed, n)
    cs = compile_system(sysm)
    assert cs.form == "mechanical" and cs.newton_structure() is not None
    a = run_compiled(cs, method, 0.0, q0, v0, 0.02, 100, kernel="spark", linear_solver="dense")
    b = run_compiled(cs, method, 0.0, q0, v0, 0.02, 100, kernel="spark", linear_solver="sparse")
    for k in ("q", "v", "constraint"):
        ref = np.asarray(getattr(a, k))
        assert np.abs(np.asarray(getattr(b, k)) - ref).max() <= 1e-12 * max(1.0, np.abs(ref).max()), k
    assert np.abs(b.constraint).max() <= 1e-12
