"""The mutation catalogue as data: semantic faults a developer of the method could plausibly make.

Each mutant replaces one exact source snippet of the package (which must occur exactly once, so
that the catalogue breaks loudly when the code moves) and names the test files most likely to
notice it (``hint``: run first, then the rest of the suite). ``ldaspark.lab.mutants.mutation`` applies
them one at a time to a scratch copy of the package and runs the suite against it.

Categories: spark-21 (the step (21a-f)), jacobian (Newton matrix and sensitivities),
time (T_i = t0 + c_i h, t1, explicit t in L and k), nonlinear-k (K = k_v at (T_j, Q_j, V_j)),
system (derived expressions of (1), (3), (8)), theorem1 (L_d, f_d^-, f_d^+), tableau (families,
omega, Lobatto IIID), conditions ((22), (23)), symmetry, comparator (sections 7.3-7.5, 8.4),
orders (order estimates), fd (finite-difference stencil of the Theorem 1 check), compiled
(fast-path kernels only).
"""
from __future__ import annotations

from .mutant import Mutant, _m


V21 = "verification/test_equations_21.py"
VTD = "verification/test_time_dependence.py"
VNL = "verification/test_nonlinear_constraint.py"
VT1 = "verification/test_theorem1.py"
VFD = "verification/test_fd_stencil.py"
VCO = "verification/test_constraint.py"
VSY = "verification/test_symmetry_23.py"
VCMP = "verification/test_comparators_7_5_8_4.py"
VRED = "verification/test_order_reduction_7_3_7_4.py"
VCND = "verification/test_conditions_22_23.py"
VORD = "verification/test_convergence_orders.py"
TSP = "tests/core/test_spark.py"
TTAB = "tests/core/test_tableau.py"
TFAST = "tests/compiled/test_fast_path.py"
TCNI = "tests/compiled/test_compiled_nonideal.py"
TORD = "tests/lab/theory/test_orders_estimates.py"
TCONV = "tests/lab/theory/test_convergence_tools.py"
# the compiled kernels live in a source string of fast.py or (after a planned move) in kernels.py
KERNELS = "compiled/fast.py|compiled/kernels.py"


CATALOGUE: tuple[Mutant, ...] = (
    # --- the IVP step (21a-f), core/spark.py -------------------------------------------------
    _m("spark-Ti-b-for-c", "core/spark.py",
       "T = [t0 + tab.c[i] * h for i in range(s)]", "T = [t0 + tab.b[i] * h for i in range(s)]",
       "stage times T_i = t0 + b_i h instead of t0 + c_i h (IVP residual)", "time", V21, VTD),
    _m("spark-t1-is-t0", "core/spark.py",
       "q1 = q0 + tab.b.dot(V) * h\n        t1 = t0 + h", "q1 = q0 + tab.b.dot(V) * h\n        t1 = t0",
       "p1 and (21f) evaluated at t0 instead of t1 = t0 + h", "time", V21, VTD),
    _m("spark-Ahat-Atilde-swapped", "core/spark.py",
       "- tab.A_hat.dot(F) * h - tab.A_tilde.dot(Rl)\n", "- tab.A_tilde.dot(F) * h - tab.A_hat.dot(Rl)\n",
       "A_hat and A_tilde swapped in (21b) (IVP)", "spark-21", V21, VORD),
    _m("spark-21b-R-sign", "core/spark.py",
       "- tab.A_hat.dot(F) * h - tab.A_tilde.dot(Rl)\n", "- tab.A_hat.dot(F) * h + tab.A_tilde.dot(Rl)\n",
       "sign of the constraint force h sum a~_ij R_j in (21b)", "spark-21", TSP, V21),
    _m("spark-21d-bhat-for-btilde", "core/spark.py",
       "- tab.b_hat.dot(F) * h - tab.b_tilde.dot(Rl)", "- tab.b_hat.dot(F) * h - tab.b_hat.dot(Rl)",
       "b_hat instead of b_tilde on the constraint force in (21d)", "spark-21", V21),
    _m("spark-21d-b-for-bhat", "core/spark.py",
       "- tab.b_hat.dot(F) * h - tab.b_tilde.dot(Rl)", "- tab.b.dot(F) * h - tab.b_tilde.dot(Rl)",
       "b instead of b_hat on the forces in (21d) (same once (22a) holds)", "spark-21", V21),
    _m("spark-21c-bhat-for-b", "core/spark.py",
       "q1 = q0 + tab.b.dot(V) * h\n        t1 = t0 + h", "q1 = q0 + tab.b_hat.dot(V) * h\n        t1 = t0 + h",
       "(21c) q1 with b_hat instead of b (same once (22a) holds)", "spark-21", V21),
    _m("spark-omega-columns-reversed", "core/spark.py",
       "r_e = tab.omega.dot(Kst)", "r_e = tab.omega[:, ::-1].dot(Kst)",
       "(21e) with omega_{i,s+1-j} (column order reversed)", "spark-21", V21),
    _m("spark-21f-last-stage", "core/spark.py",
       "G[s * n + n + (s - 1) * m:] = fin.k", "G[s * n + n + (s - 1) * m:] = Kst[-1]",
       "(21f) displaced: k(T_s, Q_s, V_s) = 0 instead of k(t1, q1, v1) = 0", "spark-21", VCO, TSP),
    _m("spark-q1-last-row-of-A", "core/spark.py",
       "q1 = q0 + tab.b.dot(V) * h\n        t1 = t0 + h", "q1 = q0 + tab.A[-1].dot(V) * h\n        t1 = t0 + h",
       "q1 in the residual from the last row of A instead of b (same only for stiffly accurate A)",
       "spark-21", TSP, VCO),
    _m("jac-21d-Lvq-dropped", "core/spark.py",
       'JdV = np.einsum("k,ab->kab", b, fin.L_vq) * h - ', 'JdV = 0 * np.einsum("k,ab->kab", b, fin.L_vq) * h - ',
       "Newton matrix: d p1 / dV misses the gyroscopic term h b_k L_vq(t1, q1, v1)", "jacobian",
       "tests/core/test_spark_jacobian.py", V21),
    _m("jac-21f-kq-dropped", "core/spark.py",
       'J[r_f:, :c_lam] = (np.einsum("k,ab->akb", b, fin.k_q) * h)',
       'J[r_f:, :c_lam] = (np.einsum("k,ab->akb", b, fin.k_q) * 0)',
       "Newton matrix: (21f) row misses h b_k k_q(t1, q1, v1) (also the BVP sensitivities)", "jacobian",
       V21, VT1),
    # --- derived expressions of the system, core/system.py ---------------------------------
    _m("system-K-at-v0", "core/system.py|core/derive.py",
       "cols.setdefault(j, []).append(e * lam_e[i])",
       "cols.setdefault(j, []).append(e.subs({x: 0 for x in Vs}) * lam_e[i])",
       "R = -K^T Psi with K = k_v evaluated at v = 0 (right only for k affine in v)", "nonlinear-k", V21, VNL),
    _m("system-Lvq-transposed", "core/system.py|core/derive.py",
       "Lvq = _jacobian(Lv, Q, eng)", "Lvq = _jacobian(Lq, V, eng)",
       "L_vq = d(grad_v L)/dq transposed (index order; same only without gyroscopic terms)", "system",
       V21, VTD),
    _m("system-energy-Lvv", "core/system.py|core/derive.py",
       "energy = eng.add([Lv[j] * Vs[j] for j in sorted(Lv)]) - L",
       "energy = eng.add([Lvv[i, j] * Vs[i] * Vs[j] for (i, j) in sorted(Lvv)]) - L",
       "energy (8) with p = L_vv v (right only for L quadratic in v without linear terms)", "system", VTD),
    _m("system-energy-sign", "core/system.py|core/derive.py",
       "energy = eng.add([Lv[j] * Vs[j] for j in sorted(Lv)]) - L",
       "energy = eng.add([Lv[j] * Vs[j] for j in sorted(Lv)]) + L",
       "energy (8) E = L_v v + L", "system", TSP),
    _m("solution-energy-at-t0", "core/spark.py",
       "E = [system.energy(bk, ts[i], Qs[i], Vs[i]) for i in range(N + 1)]",
       "E = [system.energy(bk, ts[0], Qs[i], Vs[i]) for i in range(N + 1)]",
       "reported energy (8) at (t0, q_n, v_n) instead of (t_n, q_n, v_n) (visible only for E depending on t)",
       "time", VTD),
    _m("ode-Lvt-dropped", "core/system.py",
       "rhs = np.concatenate([-Lvt[:, 0] - Lvq.dot(v)", "rhs = np.concatenate([0 * Lvt[:, 0] - Lvq.dot(v)",
       "(3a) without -grad^2_tv L (reference ODE wrong for explicitly time-dependent L)", "time", VTD),
    _m("ode-kt-dropped", "core/system.py",
       "-kt[:, 0] - kq.dot(v)])", "0 * kt[:, 0] - kq.dot(v)])",
       "(3b) without -k_t (reference ODE wrong for rheonomic k)", "time", VTD),
    _m("ode-kq-sign", "core/system.py",
       "-kt[:, 0] - kq.dot(v)])", "-kt[:, 0] + kq.dot(v)])",
       "(3b) with +k_q v", "system", VTD, VORD),
    # --- the discrete Lagrangian and forces of Theorem 1, analysis/discrete.py ---------------------
    _m("fdminus-sign", "analysis/discrete.py",
       "fm = fm + wm.dot(dV_dq0[i]) * (h * tab.b[i])", "fm = fm - wm.dot(dV_dq0[i]) * (h * tab.b[i])",
       "sign of f_d^-", "theorem1", VT1),
    _m("fdminus-index-order", "analysis/discrete.py",
       "wm = sum(LK[j] * tab.A_tilde[i, j] for j in range(s))",
       "wm = sum(LK[j] * tab.A_tilde[j, i] for j in range(s))",
       "f_d^- with a~_ji instead of a~_ij", "theorem1", VT1),
    _m("fdminus-Ahat", "analysis/discrete.py",
       "wm = sum(LK[j] * tab.A_tilde[i, j] for j in range(s))",
       "wm = sum(LK[j] * tab.A_hat[i, j] for j in range(s))",
       "f_d^- with A_hat instead of A_tilde (same for Gauss and IIIA-IIIB)", "theorem1", VT1),
    _m("fdplus-index-order", "analysis/discrete.py",
       "(tab.b_tilde[j] - tab.A_tilde[i, j])", "(tab.b_tilde[j] - tab.A_tilde[j, i])",
       "f_d^+ with a~_ji instead of a~_ij", "theorem1", VT1),
    _m("fdplus-btilde-i", "analysis/discrete.py",
       "(tab.b_tilde[j] - tab.A_tilde[i, j])", "(tab.b_tilde[i] - tab.A_tilde[i, j])",
       "f_d^+ with b~_i instead of b~_j", "theorem1", VT1),
    _m("fdplus-dVdq0", "analysis/discrete.py",
       "fp = fp - wp.dot(dV_dq1[i])", "fp = fp - wp.dot(dV_dq0[i])",
       "f_d^+ paired with dV/dq0 instead of dV/dq1", "theorem1", VT1),
    _m("forces-K-at-v0", "analysis/discrete.py",
       "K = [np.array(Kfn(T[j], *Q[j], *V[j])[0]", "K = [np.array(Kfn(T[j], *Q[j], *v0)[0]",
       "f_d^{+/-} with K_j = k_v(T_j, Q_j, v0) instead of k_v(T_j, Q_j, V_j)", "nonlinear-k", VNL),
    _m("forces-K-at-t0", "analysis/discrete.py",
       "K = [np.array(Kfn(T[j], *Q[j], *V[j])[0]", "K = [np.array(Kfn(t0, *Q[j], *V[j])[0]",
       "f_d^{+/-} with K_j at t0 instead of T_j", "time", VTD),
    _m("bvp-Ti-b-for-c", "analysis/discrete.py",
       "T = [t0 + tab.c[i] * h for i in range(s)]\n        Q = q0 + tab.A.dot(V) * h\n        q1i",
       "T = [t0 + tab.b[i] * h for i in range(s)]\n        Q = q0 + tab.A.dot(V) * h\n        q1i",
       "boundary-value residual with T_i = t0 + b_i h", "time", VTD, V21),
    _m("bvp-21f-at-t0", "analysis/discrete.py",
       "fin = sysm.stage(bk, t1, q1i, v1, bk.zeros(m), jacobian)",
       "fin = sysm.stage(bk, t0, q1i, v1, bk.zeros(m), jacobian)",
       "boundary-value residual: p1 and (21f) at t0 instead of t1", "time", VTD, V21),
    _m("bvp-p0-at-t1", "analysis/discrete.py",
       "st0 = sysm.stage(bk, t0, q0, v0, bk.zeros(m), jacobian)",
       "st0 = sysm.stage(bk, t1, q0, v0, bk.zeros(m), jacobian)",
       "boundary-value residual: p0 = grad_v L(t1, q0, v0) instead of (t0, q0, v0)", "time", VTD, V21),
    _m("Ld-time-frozen", "analysis/discrete.py",
       "Lfn(t0 + tab.c[i] * h, *Q[i], *V[i])", "Lfn(t0, *Q[i], *V[i])",
       "L_d = h sum b_i L(t0, Q_i, V_i) (time argument T_i dropped)", "time", VTD),
    _m("Ld-value-time-frozen", "analysis/discrete.py",
       "L_d = h * sum(tab.b[i] * Lfn(T[i], *Q[i], *V[i])[0] for i in range(s))",
       "L_d = h * sum(tab.b[i] * Lfn(t0, *Q[i], *V[i])[0] for i in range(s))",
       "the reported L_d (not the one Theorem 1's differences use) with L at t0 instead of T_i", "time", V21),
    _m("bvp-dq0-21f-dropped", "analysis/discrete.py",
       "dq0[self.r_f:self.r_c] = fin.k_q", "dq0[self.r_f:self.r_c] = 0 * fin.k_q",
       "sensitivity dG/dq0 misses the (21f) row k_q(t1, q1, v1)", "jacobian", VT1, V21),
    _m("bvp-21c-last-row-of-A", "analysis/discrete.py",
       "G[self.r_c:] = tab.b.dot(V) - (q1 - q0) / h", "G[self.r_c:] = tab.A[-1].dot(V) - (q1 - q0) / h",
       "boundary-value (21c) row with the last row of A instead of b", "spark-21", VT1),
    _m("bvp-21d-b-for-bhat", "analysis/discrete.py",
       "G[self.r_d:self.r_e] = fin.L_v - p0 - tab.b_hat.dot(F) * h", "G[self.r_d:self.r_e] = fin.L_v - p0 - tab.b.dot(F) * h",
       "boundary-value (21d) row with b instead of b_hat (same once (22a) holds)", "spark-21", V21, VT1),
    _m("bvp-dq0-b-for-bhat", "analysis/discrete.py",
       'np.einsum("j,jab->ab", tab.b_hat, Lqq) * h', 'np.einsum("j,jab->ab", tab.b, Lqq) * h',
       "sensitivity dG/dq0 of the (21d) row with b instead of b_hat", "jacobian", V21, VT1),
    _m("fd-forward-difference", "analysis/discrete.py",
       "[(Ld_at(dl) - Ld_at(-dl)) / (2 * dl) for dl in", "[(Ld_at(dl) - Ld_at(0 * dl)) / dl for dl in",
       "dL_d/dq by forward instead of central differences under the same Richardson weights", "fd", VT1, VFD),
    _m("fd-richardson-weight", "analysis/discrete.py",
       "R1 = (4 * D[1] - D[0]) / 3", "R1 = (2 * D[1] - D[0])",
       "Richardson weights of an order-1 stencil on a central difference", "fd", VFD, VT1),
    # --- tableaux, core/families.py -----------------------------------------------------------
    _m("tableau-arrays-20-digit-entries", "core/tableau.py",
       "ent = self.mp_entries(max(dps or 0, 20))", "ent = self.mp_entries(20)",
       "mpmath coefficients from 20-digit entries at every dps ((22) off by ~1e-21; Theorem 1's "
       "1e-20 threshold passed it)", "tableau", VT1, TTAB),
    _m("bvp-dq0-21e-constraint-major", "analysis/discrete.py",
       'np.einsum("lj,jab->lab", tab.omega, kq).reshape((s - 1) * m, n)',
       'np.einsum("lj,jab->alb", tab.omega, kq).reshape((s - 1) * m, n)',
       "(21e) rows of dG/dq0 ordered constraint-major (the same for s = 2 or m = 1: only s >= 3 with "
       "m >= 2 sees it)", "bvp", "verification/test_general_systems.py"),
    _m("iiid-exact-is-iiic", "core/families.py",
       "At = [[(C[i][j] + Cs[i][j]) * half for j in range(s)] for i in range(s)]",
       "At = C",
       "exact Lobatto IIID = IIIC instead of (IIIC + IIIC*)/2", "tableau", VCND, VSY),
    _m("iiid-numeric-is-iiic-star", "core/families.py",
       "D = [[(C[i][j] + Cs[i][j]) / 2 for j in range(s)] for i in range(s)]",
       "D = Cs",
       "numeric Lobatto IIID = IIIC* instead of (IIIC + IIIC*)/2", "tableau", TTAB, VCND),
    _m("omega-power-off-by-one", "core/families.py",
       "if omega is None:\n        omega = [[b[j] * c[j] ** i for j", "if omega is None:\n        omega = [[b[j] * c[j] ** (i + 1) for j",
       "numeric omega_ij = b_j c_j^i instead of b_j c_j^(i-1)", "tableau", TTAB, VCND),
    _m("omega-exact-power-off-by-one", "core/families.py",
       "omega = [[b[j] * c[j] ** i for j in range(s)] for i in range(s - 1)]\n    col",
       "omega = [[b[j] * c[j] ** (i + 1) for j in range(s)] for i in range(s - 1)]\n    col",
       "exact omega_ij = b_j c_j^i instead of b_j c_j^(i-1)", "tableau", VCND, VSY),
    _m("iiib-numeric-D-condition", "core/families.py",
       "col = _mp_solve(W, [b[j] * (1 - c[j] ** (k + 1)) / (k + 1) for k in range(s)])",
       "col = _mp_solve(W, [b[j] * (1 - c[j] ** k) / (k + 1) for k in range(s)])",
       "numeric Lobatto IIIB from a wrong D(s) right-hand side", "tableau", TTAB, VCND),
    _m("euler-i-node-at-t1", "core/families.py",
       'return _one_stage("euler-i", 0, 0, 1)', 'return _one_stage("euler-i", 1, 0, 1)',
       "Euler I (7.1) with c = 1: P_1, F_1, R_1 at t1 instead of t0 (visible only for L, k depending on t)",
       "tableau", V21),
    _m("euler-ii-node-at-t0", "core/families.py",
       'return _one_stage("euler-ii", 1, 1, 0)', 'return _one_stage("euler-ii", 0, 1, 0)',
       "Euler II (7.2) with c = 0: P_1, F_1, R_1 at t0 instead of t1 (visible only for L, k depending on t)",
       "tableau", V21),
    # --- exact conditions (22), (23), analysis/conditions.py -------------------------------------
    _m("cond-22b-index-order", "analysis/conditions.py",
       "b[j] * Ah[j][i]", "b[j] * Ah[i][j]",
       "(22b) checked with a^_ij instead of a^_ji", "conditions", VCND),
    _m("cond-23-index", "analysis/conditions.py",
       "e[M][r(i)][r(j)] + e[M][i][j]", "e[M][r(i)][j] + e[M][i][j]",
       "(23b-d) checked with a_{s+1-i, j} instead of a_{s+1-i, s+1-j}", "conditions", VCND),
    _m("cond-23-Ahat-dropped", "analysis/conditions.py",
       'for M, bv in (("A", "b"), ("A_hat", "b_hat"), ("A_tilde", "b_tilde")):',
       'for M, bv in (("A", "b"), ("A_tilde", "b_tilde")):',
       "(23c) on A_hat never checked", "conditions", VCND),
    _m("cond-23a-dropped", "analysis/conditions.py",
       'if any(e["c"][r(i)] + e["c"][i] != K.one for i in range(s)):', "if False:",
       "(23a) c_{s+1-i} + c_i = 1 never checked", "conditions", VCND),
    _m("cond-22b-b-for-bhat", "analysis/conditions.py",
       "- bh[i] * b[j] == K.zero", "- b[i] * b[j] == K.zero",
       "(22b) checked with b_i b_j instead of b^_i b_j (same once (22a) holds)", "conditions", VCND),
    # --- symmetry check, analysis/symmetry.py ---------------------------------------------------
    _m("symmetry-Ld-sign", "analysis/symmetry.py",
       "sL = abs(fwd.L_d + rev.L_d)", "sL = abs(fwd.L_d - rev.L_d)",
       "symmetry residual L_d(t1,q1,t0,q0) - L_d(t0,q0,t1,q1) instead of +", "symmetry", VSY),
    # --- comparators, core/comparators.py -----------------------------------------------------
    _m("irk-stage-constraint-V1", "core/comparators.py",
       "e = self._stage_evals[i]",
       "e = self.system.stage(self.backend, T[i], Q[i], self.unpack(x)[0][0], self.backend.zeros(m), jacobian)",
       "standard Gauss IRK: stage constraint k(T_i, Q_i, V_1) instead of V_i", "comparator", VRED),
    _m("modified-full-step", "core/comparators.py",
       "e = self.system.stage(bk, t0 + half, q0 + half * V[0], V[0]",
       "e = self.system.stage(bk, t0 + half, q0 + h * V[0], V[0]",
       "modified Lobatto (8.4): constraint at q0 + h V_1 instead of q0 + h/2 V_1", "comparator", VCMP),
    _m("leapfrog-first-half-step", "core/comparators.py",
       "rhs = M.dot(v) - half * g if k == 0", "rhs = M.dot(v) - h_ * g if k == 0",
       "leapfrog form after (25): first step with a full instead of a half kick", "comparator", VCMP),
    _m("mp-26a-full-step", "core/comparators.py",
       "Q1 = q + half * v  ", "Q1 = q + h_ * v  ",
       "McLachlan-Perlmutter (26a): Q_1 = q0 + h v0 instead of q0 + h/2 v0", "comparator", VCMP),
    _m("composition-order-swapped", "core/comparators.py",
       'first, second = (euler_i(), euler_ii()) if name == "euler-i-ii-composition"',
       'first, second = (euler_ii(), euler_i()) if name == "euler-i-ii-composition"',
       "Euler I-II composition run as II-I (7.5)", "comparator", VCMP),
    # --- order estimates, lab/theory/orders.py -----------------------------------------------------
    _m("orders-pairwise-log2", "lab/theory/orders.py",
       "math.log(e0 / e1) / math.log(float(hs[j]) / float(hs[j + 1]))", "math.log(e0 / e1) / math.log(2.0)",
       "pairwise orders assume step ratio 2", "orders", TORD),
    _m("orders-window-ties", "lab/theory/orders.py",
       "j - i >= best[1] - best[0]", "j - i > best[1] - best[0]",
       "asymptotic window: ties go to the larger steps (the pre-asymptotic end)", "orders", TORD),
    _m("orders-ls-window-off-by-one", "lab/theory/orders.py",
       "x = np.log(hs[win[0]:win[1] + 1])\n        y = np.log(errs[win[0]:win[1] + 1])",
       "x = np.log(hs[win[0]:win[1]])\n        y = np.log(errs[win[0]:win[1]])",
       "least-squares slope drops the last point of the window", "orders", TORD),
    _m("orders-floor-unscaled", "lab/theory/orders.py",
       "return factor * Backend(dps).eps * max(1.0, scale)", "return factor * Backend(dps).eps",
       "round-off floor not scaled by |reference|", "orders", TORD, TCONV),
    _m("orders-verdict-one-sided", "lab/theory/orders.py",
       'return "holds" if abs(o - c) <= tol else "FAILS"', 'return "holds" if o - c <= tol else "FAILS"',
       "verdict accepts any order below the claim", "orders", TCONV, TORD),
    _m("orders-psi-stage-times", "lab/theory/orders.py",
       "t_last = bk.scalar(t_end) - h", "t_last = bk.scalar(t_end)",
       "Psi_i of the last step compared with psi(T + c_i h) instead of psi(T - h + c_i h)", "orders", TORD),
    # --- compiled fast path only, compiled/fast.py (kernels) -----------------------------------
    _m("compiled-21d-gradU-sign", "compiled/kernels_mech.py",
       "wh = Ah[i, j] if i < s else bh[j]\n                wt = At[i, j] if i < s else bt[j]\n                acc2 += wh",
       "wh = Ah[i, j] if i < s else -bh[j]\n                wt = At[i, j] if i < s else bt[j]\n                acc2 += wh",
       "compiled kernel: sign of h sum b^_j grad U_j in (21d)", "compiled", TFAST),
    _m("compiled-q1-last-row-of-A", "compiled/newton.py",
       "acc += bw[j] * V[j, a]\n        q1[a] = q0[a] + h * acc",
       "acc += A[s - 1, j] * V[j, a]\n        q1[a] = q0[a] + h * acc",
       "compiled kernel: q1 in the residual from the last row of A instead of b", "compiled", TFAST),
    _m("compiled-nonideal-N-unscaled", "compiled/kernels_general.py",
       "KTL[j, a] -= h * Nst[j, a]", "KTL[j, a] -= Nst[j, a]",
       "compiled kernel: nonideal term N not scaled by h in R = -K^T Lambda / h + N (3.3)", "compiled", TCNI),
    _m("compiled-nonideal-Npsi-sign", "compiled/kernels_general.py",
       "J[i * n + a, sn + k * m + l] -= wk_t * Np[k, a, l]", "J[i * n + a, sn + k * m + l] += wk_t * Np[k, a, l]",
       "compiled kernel: sign of the N_psi block of the Newton matrix (3.3)", "compiled", TCNI),
    # --- rank decisions at full precision (analysis/discrete.py) ------------------------------------
    _m("rank-small-sigmas-float64", "analysis/discrete.py",
       "[max(x, floor) for x in small]", "[max(mpmath.mpf(float(v)), floor) for v in s64[k:]]",
       "rank decision: the candidate singular values taken from the float64 SVD instead of the "
       "full-precision Schur complement", "theorem1", "tests/core/test_flint_backend.py", VT1),
)

# A fixed subset for ``--quick``: one per main area, each killed fast by its hint files.
# The last four are one per class of faults the suite once missed: a pre-asymptotic
# sweep, an event direction, shared state between copies, HDF5 byte strings; their hints are
# single tests, so the quick run (``.ci/run``) stays a few minutes on 2 cores. The block-sparse
# Newton solver's fill (killed in ~2 s by tests/compiled/test_sparse_newton.py) closes the list.
QUICK = ("spark-Ahat-Atilde-swapped", "fdplus-index-order", "system-K-at-v0", "Ld-time-frozen",
         "orders-pairwise-log2", "cond-22b-index-order", "teeth-audit-coarsest-pair",
         "teeth-event-direction-negative-swapped", "teeth-with-params-shared-store",
         "teeth-h5-byte-strings-as-float", "sparse-fill-lower-missing")



def _area_catalogues() -> tuple[Mutant, ...]:
    """Mutants of each area (``ldaspark/lab/mutants/catalogue/<area>.py``, each a ``MUTANTS`` tuple),
    in module-name order, so that the areas' catalogues grow without editing one shared list."""
    import importlib
    import pkgutil

    from . import catalogue
    found = []
    for info in sorted(pkgutil.iter_modules(catalogue.__path__), key=lambda i: i.name):
        found.extend(importlib.import_module(f"{catalogue.__name__}.{info.name}").MUTANTS)
    return tuple(found)


CATALOGUE = CATALOGUE + _area_catalogues()
if len({m.id for m in CATALOGUE}) != len(CATALOGUE):
    raise ImportError("mutation catalogue: duplicate mutant ids")


def by_id(mutant_id: str) -> Mutant:
    for m in CATALOGUE:
        if m.id == mutant_id:
            return m
    raise KeyError(mutant_id)
