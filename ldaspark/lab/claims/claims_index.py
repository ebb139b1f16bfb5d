"""Claims index: every numbered equation and every claim sentence of sections 2-8 of the paper,
with the test that checks it (``file::test_name``) and its status.

Status: ``checked`` (a test with a negative control measures it), ``not checkable`` (a
definition, an assumption on the data, a continuous functional principle, a statement about
other papers, ...; the reason says which), ``not checked`` (checkable, not measured here; the
reason says why). ``claims_index_markdown()`` renders the table (written into
reports/claims.md by ``ldaspark.lab.reports.claims``); ``tests/lab/claims/test_claims_index.py`` verifies that
every referenced test exists.
"""
from __future__ import annotations

CHECKED, NOT_CHECKABLE, NOT_CHECKED = "checked", "not checkable", "not checked"

E5 = "verification/test_exact_discrete_5.py"
D1 = "verification/test_definition1_15.py"
EN = "verification/test_energy_balance_2_2.py"
S7 = "verification/test_section7_reductions.py"
VO = "verification/test_variational_order.py"
T1 = "verification/test_theorem1.py"
SY = "verification/test_symmetry_23.py"
CO = "verification/test_conditions_22_23.py"
CN = "verification/test_constraint.py"
OR = "verification/test_convergence_orders.py"
RD = "verification/test_order_reduction_7_3_7_4.py"
CM = "verification/test_comparators_7_5_8_4.py"
SC = "verification/test_scenes_section_8.py"
HO = "verification/test_holonomic_5_1.py"
SP = "tests/core/test_spark.py"
TB = "tests/core/test_tableau.py"
BI = "tests/api/test_bad_input.py"
EX = "tests/lab/reports/test_extremes.py"
EL = "tests/ensemble/test_ensemble.py"

# (ref, section, claim, tests, status, note)
CLAIMS: tuple[tuple[str, str, str, tuple[str, ...], str, str], ...] = (
    ("(1a)-(1c)", "2", "Lagrange equations of the second kind with ideal nonholonomic constraints",
     (f"{E5}::test_exact_flow_against_skate_closed_form",), CHECKED,
     "the model; its solutions (exact flow) match the skate's closed form to 1e-30"),
    ("(1d)", "2", "K := k_v", (f"{SP}::test_energy_expression_is_8",), NOT_CHECKABLE,
     "definition; derived symbolically by LagrangianSystem"),
    ("(2)", "2", "constraints affine in v; 'the assumption (2) will actually not be needed'",
     (f"{D1}::test_15a_15b_time_dependent_L_and_nonlinear_k",), CHECKED,
     "(15a-b) hold along trajectories for k = v3 - q2 v1 + v1^2/4"),
    ("(3a)", "2.1", "expanded (1b): L_vv v' + K^T psi = -L_tv - L_qv v + L_q",
     (f"{E5}::test_exact_flow_against_independent_references",), CHECKED,
     "the underlying ODE integrated two independent ways (collocation, mpmath Taylor) agrees to 1e-28"),
    ("(3b)", "2.1", "differentiated constraint K v' = -k_t - k_q v",
     (f"{E5}::test_16_18_exact_momentum_identities",), CHECKED,
     "k is constant along (3a-b) off C_d (first integral) and zero on C_d"),
    ("2.1-cost", "2.1", "it is advantageous to use (1b) rather than (3a), which needs L_tv and the Coriolis term L_qv v",
     (), NOT_CHECKABLE, "a design statement; the SPARK code uses (1b) and never forms L_tv or L_qv v"),
    ("(4)", "2.1", "the saddle matrix [[L_vv, K^T], [K, 0]] is nonsingular",
     (f"{BI}::test_singular_Lvv_on_ker_K_is_a_setup_error", f"{BI}::test_rank_deficient_K_is_a_setup_error"),
     NOT_CHECKABLE, "an assumption on the data; enforced as an input check (SingularSaddleError)"),
    ("(5)", "2.1", "regular Lagrangian: L_vv nonsingular (a sufficient condition for (4) with K of full rank)",
     (f"{BI}::test_singular_Lvv_with_regular_saddle_fails_in_newton_not_silently",), NOT_CHECKABLE,
     "an assumption; (4) is what the methods need (a singular L_vv with regular (4) is accepted)"),
    ("2.1-index", "2.1", "under (4) the equations (1) are DAEs of index 2; existence and uniqueness for consistent data",
     (), NOT_CHECKABLE, "analytical statements (index, existence) - not a finite computation"),
    ("(6a)-(6b), (7)", "2.1", "underlying forced Lagrangian system with f_L = -K^T Psi; k are first integrals of (6)-(7)",
     (f"{E5}::test_16_18_exact_momentum_identities",), CHECKED,
     "off C_d k(t, q, v) stays at k0 != 0 along the forced flow (to the stage order of the collocation)"),
    ("(8)", "2.2", "energy E = L_v v - L", (f"{SP}::test_energy_expression_is_8",), CHECKED, "symbolic"),
    ("2.2-balance", "2.2", "dE/dt = -psi^T K v - L_t",
     (f"{EN}::test_energy_balance_2_2_exact_nonconservative", f"{EN}::test_energy_balance_2_2_discrete_order"),
     CHECKED, "pointwise and integrated along exact solutions (<= 1e-22); discrete: Delta E - stage quadrature "
     "= O(h^(p+1)) while Delta E = O(h); exact for Gauss when L_t = 0 and E is quadratic"),
    ("2.2-conserved", "2.2", "scleronomic k linear in v and autonomous L conserve energy",
     (f"{EN}::test_energy_balance_2_2_exact_conserved",), CHECKED,
     "finding: a rheonomic k linear in v (K v = k = 0) conserves E as well - the condition is sufficient only"),
    ("(9a)-(9b)", "3", "Lagrange-d'Alembert principle: virtual work vanishes for K delta q = 0", (), NOT_CHECKABLE,
     "a differential principle; its consequence (1b) is what the solvers integrate"),
    ("(9c)", "3", "Chetaev's rule for nonlinear constraints gives (1d)",
     (f"{D1}::test_15a_15b_time_dependent_L_and_nonlinear_k",), NOT_CHECKABLE,
     "a modelling rule (which constraints are ideal); nonlinear k is exercised, not derived"),
    ("3-gauss", "3", "Gauss' principle of least constraint is equivalent", (), NOT_CHECKABLE,
     "a statement about another principle; not implemented"),
    ("(10)", "3.1", "skew critical problem equivalent to the Lagrange-d'Alembert principle (scleronomic, linear)", (),
     NOT_CHECKABLE, "a statement about a functional on C^1 curves"),
    ("3.1-vakonomic", "3.1", "Hamilton's principle leads to the vakonomic equations, which disagree with experiment",
     (), NOT_CHECKABLE, "no vakonomic model or experiment here"),
    ("3.2", "3.2", "integral Lagrange-d'Alembert principle for forced systems, plus k = 0", (), NOT_CHECKABLE,
     "a continuous functional identity; its discrete form (11)/(14) is checked as (13)/(15a)"),
    ("3.3", "3.3", "SPARK methods deal with nonideal constraints without difficulty",
     ("verification/test_general_scenes.py::test_nonideal_orders_every_family_friction_skate",
      "tests/core/test_nonideal.py::test_newton_matrix_with_nonideal_term_matches_differences"), CHECKED,
     "friction skate: every family keeps its order with R = -K^T psi + N (ledger claim nonideal-3.3)"),
    ("(11)", "4.1", "forced discrete Lagrange-d'Alembert principle, equivalent to (13)",
     (f"{D1}::test_15a_15b_along_trajectory",), CHECKED, "(13) is (15a); variations by finite differences"),
    ("(12a)-(12b)", "4.1", "exact discrete forces f_d^{E-+} = int f_L^T d_q q dt",
     (f"{E5}::test_16_18_exact_momentum_identities",), CHECKED,
     "computed by quadrature with the exact flow's sensitivities; they satisfy (16), (18)"),
    ("(13)", "4.1", "forced discrete Euler-Lagrange equations",
     (f"{D1}::test_15a_15b_along_trajectory", f"{E5}::test_20_exact_discrete_euler_lagrange"), CHECKED,
     "SPARK trajectories (N = 10) and two exact steps"),
    ("4.1-antisymmetry", "4.1", "L_d^E, f_d^{E+-} are anti-symmetric under exchange of the endpoints",
     (f"{E5}::test_antisymmetry_exact_4_1",), CHECKED, "<= 1e-22 off C_d; control: the wrong pairing"),
    ("4.1-require", "4.1", "discrete anti-symmetries could be required (hold for symmetric methods)",
     (f"{SY}::test_symmetry_symmetric_methods", f"{SY}::test_symmetry_fails_for_euler"), CHECKED,
     "f_d symmetry on variations tangent to C_d"),
    ("4.1-ivp", "4.1", "nonsymmetric methods may be appropriate for initial value problems", (), NOT_CHECKABLE,
     "an opinion"),
    ("(14a)-(14b)", "4.2", "Definition 1: nonholonomically constrained discrete principle with c = 0",
     (f"{D1}::test_15a_15b_along_trajectory", f"{CN}::test_constraint_mpmath"), CHECKED,
     "c(t_k, q_k, t_{k+1}, q_{k+1}) = k(t_{k+1}, q_{k+1}, v_{k+1}) at round-off"),
    ("4.2-c0", "4.2", "assumption c(t, q, t, q) = 0", (), NOT_CHECKABLE,
     "h = 0 is outside the domain of (21) (the step equations degenerate)"),
    ("(15a)", "4.2", "constrained discrete Euler-Lagrange equations",
     (f"{D1}::test_15a_15b_along_trajectory", f"{D1}::test_15a_fails_for_22b_breaking_tableau"), CHECKED,
     "<= 1e-25 along 10 steps, D2/D4 L_d by finite differences; control: (22b) broken"),
    ("(15b)", "4.2", "c(t_{k-1}, q_{k-1}, t_k, q_k) = c(t_k, q_k, t_{k+1}, q_{k+1}); (15b) implies (14b)",
     (f"{D1}::test_15a_15b_along_trajectory",), CHECKED, "<= 1e-40; control: secant velocity for u"),
    ("4.2-Phi", "4.2", "(15) define a map Phi on C_d",
     (f"{T1}::test_wellposedness_classes",), CHECKED,
     "finding: for some method/scene pairs the boundary-value solve is singular (L_d is not a function of the endpoints)"),
    ("4.2-literature", "4.2", "consistent with Marsden-West, generalizes Cortes, awaited by McLachlan-Perlmutter", (),
     NOT_CHECKABLE, "statements about other papers"),
    ("5-Ld", "5", "L_d^E as the action of the solution through (t0, q0), (t1, q1); p0, p1",
     (f"{E5}::test_exact_flow_against_skate_closed_form",), CHECKED,
     "against mpmath.quad of L along the closed form"),
    ("5-derivation", "5", "d_q0 L_d^E = int Psi^T K d_q0 q dt - p0^T (with L_v, not the printed L_q, in the t1 boundary term)",
     (f"{E5}::test_16_18_exact_momentum_identities",), CHECKED,
     "the printed L_q(t1, ...) d_q0 q1 is a typo, harmless since d_q0 q1 = 0"),
    ("(16)", "5", "d_q0 L_d^E = -p0^T - f_d^{E-T}", (f"{E5}::test_16_18_exact_momentum_identities",), CHECKED,
     "FD at 52 digits, <= 1e-22, on and off C_d; control: without the force"),
    ("(17)", "5", "f_d^{E-T} = int_{t0}^{t1} (int_{t0}^s Psi^T K dt) d_q0 v(s) ds", (f"{E5}::test_17_19_integral_forms",),
     CHECKED, "against (12a) by quadrature"),
    ("(18)", "5", "d_q1 L_d^E = p1^T - f_d^{E+T}", (f"{E5}::test_16_18_exact_momentum_identities",), CHECKED, ""),
    ("(19)", "5", "f_d^{E+T} = -int_{t0}^{t1} (int_s^{t1} Psi^T K dt) d_q1 v(s) ds", (f"{E5}::test_17_19_integral_forms",),
     CHECKED, "against (12b)"),
    ("(20a)", "5", "f_d^{E+}(t_{k-1}, q_{k-1}, t_k, q_k) in integral form", (f"{E5}::test_20_exact_discrete_euler_lagrange",),
     CHECKED, "the first line prints K^T for K (dimension slip)"),
    ("(20b)", "5", "f_d^{E-}(t_k, q_k, t_{k+1}, q_{k+1}) in integral form",
     (f"{E5}::test_20_exact_discrete_euler_lagrange", f"{E5}::test_17_19_integral_forms"), CHECKED,
     "finding: the printed inner limits int_s^{t_k} give -f_d^{E-}; int_{t_k}^s is correct (as (17))"),
    ("5-del", "5", "the exact forces satisfy the forced discrete Euler-Lagrange equations",
     (f"{E5}::test_20_exact_discrete_euler_lagrange",), CHECKED, "two exact steps, D2/D4 by FD"),
    ("5-generating", "5", "for unconstrained systems L_d^E is a type I generating function", (), NOT_CHECKED,
     "L_d^E itself not; its discrete analogue, the SPARK L_d (13) at m = 0, is checked as a type I generating "
     "function by verification/test_unconstrained_prk.py"),
    ("5.1", "5.1", "holonomic constraints: f_d^{E+} = f_d^{E-} = 0",
     (f"{E5}::test_5_1_exact_forces_vanish_holonomic", f"{HO}::test_holonomic_forces_small"), CHECKED,
     "on variations tangent to g = 0 (the derivation's d_q0 g(q(t)) = 0); the full covectors are normal reactions"),
    ("(21a)-(21f)", "6", "the s-stage SPARK method for (1)", (f"{SP}::test_skate_gauss2_error_and_constraint",),
     NOT_CHECKABLE, "definition; implemented in ldaspark.core.spark"),
    ("6-omega", "6", "omega_ij = b_j c_j^(i-1) is a valid choice", (f"{CN}::test_constraint_mpmath",), CHECKED,
     "the built-in methods use it and converge with the claimed orders"),
    ("6-map", "6", "a map (t1, q1, v1) = Phi_h(t0, q0, v0) exists for small |h|", (f"{CN}::test_constraint_float64",),
     CHECKED, "every built-in method steps on every scene"),
    ("(22a)-(22b)", "6", "Theorem 1: under (22) SPARK is an LdA integrator with the printed L_d, f_d^+-",
     (f"{T1}::test_theorem1_builtin", f"{T1}::test_negative_controls_theorem1"), CHECKED,
     "<= min(1e-20, the residual's derived bound 10 FD error + 1e3 cond(J) 10^-60) with FD at 60 digits; controls break (22)"),
    ("(23a)-(23d)", "6", "under (23) the method is symmetric and L_d, f_d are anti-symmetric",
     (f"{SY}::test_symmetry_symmetric_methods", f"{SY}::test_symmetry_fails_for_euler"), CHECKED, ""),
    ("6-adjoint", "6", "adjoint internal values T_{s+1-i}, Q_{s+1-i}, V_{s+1-i}, Psi_{s+1-i}",
     (f"{SY}::test_symmetry_symmetric_methods",), CHECKED, "the reversed solve starts from them and converges to them"),
    ("7-families", "7", "Gauss and Lobatto SPARK families satisfy Theorem 1",
     (f"{CO}::test_22a_22b_23_families",), CHECKED, "exact arithmetic"),
    ("7-orders", "7", "Gauss SPARK order 2s, Lobatto SPARK order 2s-2",
     (f"{OR}::test_order_skate_float64", f"{OR}::test_order_particle_against_ode_reference"), CHECKED, ""),
    ("7.1", "7.1", "Euler I: tableau; not symmetric; reduces to the printed q1/v1/Psi_1 system with V_1 = v_1",
     (f"{TB}::test_euler_i_7_1", f"{CO}::test_euler_satisfies_22_not_23", f"{S7}::test_section7_printed_systems"),
     CHECKED, "equals the printed system solved on its own, <= 1e-35"),
    ("7.1-linear", "7.1", "Euler I is linearly implicit when K and b are constant", (f"{S7}::test_linearly_implicit_7",),
     CHECKED, "one Newton iteration from a generic start; control: K(q)"),
    ("7.1-MP", "7.1", "this is [17, (4.17)] up to a typo", (), NOT_CHECKABLE, "a statement about another paper"),
    ("7.2", "7.2", "Euler II: tableau; not symmetric; printed system with V_1 = v_0; linearly implicit",
     (f"{TB}::test_euler_ii_7_2", f"{S7}::test_section7_printed_systems", f"{S7}::test_linearly_implicit_7"),
     CHECKED, "one Newton iteration from V_1 = v_0 even with K(q), b(q)"),
    ("7.3", "7.3", "1-stage Gauss SPARK = the printed midpoint system; it satisfies (23)",
     (f"{TB}::test_gauss_1_midpoint_7_3", f"{S7}::test_section7_printed_systems",
      f"{CO}::test_22a_22b_23_families"), CHECKED,
     "control: Lobatto IIIA-B 2 does not solve it"),
    ("7.3-irk", "7.3", "the standard 1-stage Gauss IRK violates (1c) and has order 1",
     (f"{RD}::test_standard_gauss_irk_violates_k_at_t1", f"{RD}::test_standard_gauss_irk_1_q_v_order_is_2_not_the_claimed_1"),
     CHECKED, "finding: q and v converge with order 2, not 1"),
    ("7.4", "7.4", "2-stage Gauss SPARK: tableau, symmetric; the standard 2-stage Gauss IRK has order 2",
     (f"{TB}::test_gauss_2_7_4", f"{RD}::test_standard_gauss_irk_2_has_order_2"), CHECKED, ""),
    ("(24)", "7.5", "2-stage Lobatto IIIA-B SPARK method as printed", (f"{TB}::test_lobatto_iiia_iiib_2_7_5",), CHECKED, ""),
    ("7.5-composition", "7.5", "not the composition of Euler I and II with h/2",
     (f"{CM}::test_euler_ii_then_i_is_not_lobatto_but_is_mclachlan_perlmutter",), CHECKED, ""),
    ("(25)", "7.5", "the (q1, V1, Psi_1) system and the leapfrog form",
     (f"{CM}::test_leapfrog_form_equals_lobatto_iiia_iiib_2",), CHECKED,
     "the linearity of (25) for constant K, b is not measured separately"),
    ("7.5-leapfrog", "7.5", "step-by-step form with v_{k+1/2}; v_k and Psi_{2,k} are not needed",
     (f"{CM}::test_leapfrog_form_equals_spark_at_30_digits",), CHECKED, ""),
    ("7.5-literature", "7.5", "analog of Stormer/Verlet/RATTLE; not equivalent to [20, (11)]", (), NOT_CHECKABLE,
     "statements about other methods and papers"),
    ("(26a)-(26d)", "7.5", "McLachlan-Perlmutter 2-stage Lobatto IIIB-A LDA method; semi-implicit, grad U once per step",
     (f"{CM}::test_mclachlan_perlmutter_satisfies_26", f"{CM}::test_grad_U_once_per_step"), CHECKED, ""),
    ("7.6", "7.6", "2-stage Lobatto IIIA-B-D SPARK: tableau, satisfies (23)",
     (f"{TB}::test_lobatto_iiia_iiib_iiid_2_7_6", f"{CO}::test_22a_22b_23_families"), CHECKED, ""),
    ("8.1-8.3", "8", "energy errors of the particle, skate, robot remain bounded (Figs. 1-3)",
     (f"{EX}::test_long_run_constraint_at_roundoff_energy_bounded",), CHECKED, "reports/energy.md reproduces the figures"),
    ("8-reversible", "8", "the scenes are reversible under (q, v) -> (q, -v)",
     (f"{EX}::test_time_reversal_symmetric_returns_to_roundoff",),
     CHECKED, "time reversal of the symmetric methods returns to round-off"),
    ("8.4-E0", "8.4", "E(q_j0, v_j0) = 3.06 for all j", (f"{SC}::test_8_4_initial_data_energy_is_3_06",), CHECKED, ""),
    ("8.4-constraint", "8.4", "the printed 8.4 constraint is nonholonomic",
     (f"{SC}::test_8_4_printed_constraint_is_a_time_derivative",), CHECKED,
     "finding: as printed it is the time derivative of q1 + sum q_i^2/2 (holonomic)"),
    ("8.4-modified", "8.4", "the modified Lobatto IIIA-B 2 method with k(t0 + h/2, q0 + h/2 V_1, V_1) = 0",
     (f"{CM}::test_modified_satisfies_midpoint_constraint_and_lobatto_does_not",), CHECKED, ""),
    ("8.4-similar", "8.4", "the three methods of Fig. 4 behave very similarly", (), NOT_CHECKED,
     "measured in reports/energy.md (Fig. 4), not asserted by a test (a judgement on a plot)"),
    ("8.4-random-walk", "8.4", "energy error behaves like a random walk, sqrt(mu) ~ h^2 sqrt(t)",
     (f"{EL}::test_fit_growth_recovers_exponents",), CHECKED, "reports/energy.md (Fig. 4) measures the exponent"),
)


NUMBERED_EQUATIONS = tuple(
    ["(1a)", "(1b)", "(1c)", "(1d)", "(2)", "(3a)", "(3b)", "(4)", "(5)", "(6a)", "(6b)", "(7)", "(8)",
     "(9a)", "(9b)", "(9c)", "(10)", "(11)", "(12a)", "(12b)", "(13)", "(14a)", "(14b)", "(15a)", "(15b)",
     "(16)", "(17)", "(18)", "(19)", "(20a)", "(20b)"]
    + [f"(21{x})" for x in "abcdef"] + ["(22a)", "(22b)"] + [f"(23{x})" for x in "abcd"]
    + ["(24)", "(25)"] + [f"(26{x})" for x in "abcd"])


def equations_in(ref: str) -> set[str]:
    """Equation labels named by a ref, ranges expanded: '(21a)-(21c), (7)' -> (21a), (21b), (21c), (7)."""
    out = set()
    for part in ref.split(","):
        part = part.strip()
        if "-" in part and part.startswith("(") and part.endswith(")"):
            a, b = part.split("-", 1)
            num, la, lb = a[1:-2], a[-2], b[-2]
            if a[-2].isalpha() and b[-2].isalpha() and b[1:-2] == num:
                out |= {f"({num}{chr(c)})" for c in range(ord(la), ord(lb) + 1)}
                continue
        if part.startswith("("):
            out.add(part)
    return out


def _cell(x: str) -> str:
    return str(x).replace("|", "\\|").replace("\n", " ")


def claims_index_markdown() -> str:
    """The index as a markdown table (pipes in cells escaped)."""
    n = {s: sum(1 for c in CLAIMS if c[4] == s) for s in (CHECKED, NOT_CHECKABLE, NOT_CHECKED)}
    lines = ["## Claims index (sections 2-8)", "",
             f"{len(CLAIMS)} entries: {n[CHECKED]} checked, {n[NOT_CHECKABLE]} not checkable, "
             f"{n[NOT_CHECKED]} not checked. Each test is `file::name`.", "",
             "| ref | section | claim | test | status | note |", "|---|---|---|---|---|---|"]
    for ref, sec, claim, tests, status, note in CLAIMS:
        t = "<br>".join(f"`{_cell(x)}`" for x in tests) if tests else "-"
        lines.append(f"| {_cell(ref)} | {_cell(sec)} | {_cell(claim)} | {t} | {status} | {_cell(note) or '-'} |")
    return "\n".join(lines) + "\n"


# The claims the ledger (``ldaspark verify``, ``ldaspark.lab.claims.ledger`` and its claim groups)
# records, each with its negative control: a record expected to fail, run through the same check on
# an input for which the claim does not hold. ``ledger_control_problems`` holds a ledger's records
# against this list (tests/lab/claims/test_claims_controls.py).
LEDGER_CLAIMS: dict[str, str] = {
    "22a": "Gauss 2 with b_hat_1 + 1/10",
    "22b": "Gauss 2 / Lobatto IIIA-B 3 with one A_hat entry + 1/10, Gauss 2 with b_hat_1 + 1/10",
    "23": "Euler I, II (not symmetric) and the perturbed tableaux",
    "5.1-holonomic": "the SPARK covector without the projection onto the tangent space (the normal reaction)",
    "implicit-function": "Gauss 1 with b = 0: q1 = q0 whatever V, the BVP is singular",
    "theorem1-q0": "the (22b)-breaking tableaux",
    "theorem1-q1": "the (22)-breaking tableaux",
    "symmetry-Ld": "Euler I, II",
    "symmetry-fd-plus": "Euler I, II",
    "symmetry-fd-minus": "Euler I, II",
    "symmetry-Phi": "Euler I, II",
    "constraint": "the standard 2-stage Gauss IRK ((21f) not imposed)",
    "gauge-invariance": "the singular pairs: the null vector moves V, L_d moves along it",
    "theorem1-general-q0": "Gauss 2 with A_hat_12 + 1/10",
    "theorem1-general-q1": "Gauss 2 with A_hat_12 + 1/10",
    "symmetry-general": "Euler I",
    "constraint-general": "the standard 2-stage Gauss IRK ((21f) not imposed)",
    "order-general-scenes": "Euler I measured against the 1-stage Gauss order 2",
    "nonideal-3.3": "the ideal skate (N dropped) against the nonideal reference",
    "15a": "Gauss 2 with A_hat_12 + 1/10",
    "15b": "the left end point off C_d",
    "16": "dL_d^E/dq0 without the force",
    "18": "dL_d^E/dq1 without the force",
    "17-integral": "(17) with the inner integral over [s, t1]",
    "19-integral": "(19) with the inner integral over [t0, s]",
    "20-integral": "(20b) as printed",
    "antisymmetry-exact": "the wrong pairing f_d^E+(rev) + f_d^E+(fwd)",
    "5.1-exact": "the nonholonomic particle",
    "variational-order": "Gauss 2 with A_hat_12 + 1/10 against Gauss 2's order 5",
    "energy-balance-2.2": "the balance without L_t / without the psi term",
    "euler-i-reduction": "the Euler II step against the printed Euler I system",
    "euler-ii-reduction": "the Euler I step against the printed Euler II system",
    "midpoint-7.3": "Lobatto IIIA-B 2 against the printed midpoint system",
    "linearly-implicit-7": "Euler I with K(q)",
}


def ledger_control_problems(records, claims=None) -> list[str]:
    """What keeps a ledger's records from the contract "every claim has a negative control": a
    claim of ``claims`` (default ``LEDGER_CLAIMS``) with records but none expected to fail and
    decided (a control recorded not-applicable shows nothing), and a recorded claim that is not
    indexed. [] when the contract holds. A claim without records (the quick ledger leaves out
    5.1-holonomic) is not a problem here."""
    claims = LEDGER_CLAIMS if claims is None else claims
    seen = list(dict.fromkeys(r["claim"] for r in records))
    out = [f"{c}: not in the index of ledger claims" for c in seen if c not in claims]
    for c in seen:
        if c in claims and not any(r["claim"] == c and r["expected"] == "fail" and r["status"] != "not-applicable"
                                   for r in records):
            out.append(f"{c}: no negative control (no decided record expected to fail)")
    return out
