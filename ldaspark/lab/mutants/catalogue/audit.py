"""Mutants of the audit's precision logic: how the precision the entries carry is
read (decimals, float64), how a condition is decided against it (balls, exact budget), zero
denominators and the verdict's disagreement sentence."""
from ..mutant import _m

TPREC = "tests/lab/theory/test_audit_precision.py"
TAUD = "tests/lab/theory/test_audit.py"
T = TPREC + "::"
TPW = "tests/lab/theory/test_audit_printed_writings.py"

MUTANTS = (
    _m("audit-decimal-literal-exact", "core/numbers.py",
       "rad = literal_radius(text, self.D, self.F, self.float_like, self.json)", "rad = 0",
       "a decimal literal taken as exact (no uncertainty from its digits): a (22) pair solved at 40 "
       "digits is 'violated' at 1e-41", "conditions",
       T + "test_22_pair_solved_at_40_digits_passes_and_a_1e10_change_fails_with_its_residual", TPREC),
    _m("audit-decimals-decided-exactly", "lab/theory/audit.py",
       'elif arith == "auto" and tab.known_exactly:', 'elif arith == "auto" and tab.is_exact:',
       "decimal entries sent to the exact decision (read as exact rationals: the original bug, "
       "Gauss-2 at 40 digits predicted order 2)", "conditions",
       T + "test_cli_decimal_tableau_exit_0_and_arithmetic_in_json", TPREC),
    _m("audit-decimal-radius-wrong-digit", "core/numbers.py",
       "    e = adjusted - digits_given + 1", "    e = adjusted - digits_given - 1",
       "decimal uncertainty from the wrong digit count (half a unit in the (D+2)-th digit: 100x too "
       "small)", "conditions",
       T + "test_22_pair_solved_at_40_digits_passes_and_a_1e10_change_fails_with_its_residual", TPREC),
    _m("audit-decimal-digits-tableau-max", "core/numbers.py",
       "full = sig >= LONG_DECIMAL or sig >= digits", "full = sig >= digits",
       "every decimal literal credited with the longest literal's digits (entries printed to "
       "different precisions)", "conditions",
       T + "test_entries_printed_to_different_digits_keep_their_own", TPREC),
    _m("audit-short-decimal-own-digits", "core/numbers.py",
       "full = sig >= LONG_DECIMAL or sig >= digits", "full = True",
       "a short terminating decimal ('0.5') known only to its own digit (0.5 +- 0.05 beside 40-digit "
       "entries)", "conditions",
       T + "test_short_decimals_are_terminating_expansions", TPREC),
    _m("audit-fixed-point-places-ignored", "core/numbers.py",
       "r = max(r, _half_place(places))", "r = r",
       "a table printed to F places read as printed to significant digits only ('0.0416667' in a "
       "7-place table known to 5e-10: Lobatto IIIA-IIIB 3 'violates' (22b))", "conditions",
       TPW + "::test_every_writing_satisfies_22_and_is_consistent", TPW),
    _m("audit-float-writing-strings-exact", "core/numbers.py",
       "(float_like or (json and digits <= FLOAT64_REPR_DIGITS))", "(json and digits <= FLOAT64_REPR_DIGITS)",
       "a float64's repr written as a string (or beside 30-digit numbers) known to its digits only, "
       "not to half an ulp ('0.16666666666666666' is 6.7e-18 from 1/6)", "conditions",
       TPW + "::test_every_writing_satisfies_22_and_is_consistent", TPW),
    _m("audit-violation-radius-largest", "lab/theory/audit_checks.py",
       "return (worst if not ok else largest), label, ok, (rad if ok else worst_rad)",
       "return (worst if not ok else largest), label, ok, rad",
       "a violation compared in its message with the largest radius of all entries, not the violated "
       "one's ('2.29e-09, beyond the uncertainty 1.0e-08')", "conditions",
       TPW + "::test_a_coefficient_moved_in_its_6th_digit_fails_22b", TPW),
    _m("audit-undecided-order-fails", "lab/theory/audit_checks.py",
       "if not math.isfinite(obs) and efloor > wfloor:", "if False:",
       "an order the entries' digits cannot show (every error within what they change) failed as the "
       "method's", "conditions",
       TPW + "::test_convergence_hidden_by_the_entries_is_undecided_not_failed", TPW),
    _m("audit-float64-exact", "core/numbers.py",
       "return flint.arb(flint.fmpq(q.numerator, q.denominator)) + flint.arb(0, abs(flint.arb(x)) * flint.arb(2) ** -53)",
       "return flint.arb(flint.fmpq(q.numerator, q.denominator))",
       "a float64 entry taken as exactly its binary value (no half-ulp uncertainty)", "conditions",
       TAUD + "::test_float_tableau_tolerance_and_worst_entry", TAUD, TPREC),
    _m("audit-ball-zero-by-midpoint", "analysis/order_conditions.py",
       "return bool(x.contains(0))", "return bool(x.mid() == 0)",
       "a condition decided by its value as written compared with 0, ignoring the uncertainty",
       "conditions",
       T + "test_22_pair_solved_at_40_digits_passes_and_a_1e10_change_fails_with_its_residual", TPREC),
    _m("audit-nan-ball-is-zero", "analysis/order_conditions.py",
       "if not x.is_finite():    # a NaN ball", "if False:    # a NaN ball",
       "a NaN ball (which contains 0 for arb) counted as a condition that holds", "conditions",
       T + "test_a_nan_ball_is_never_a_zero", TPREC),
    _m("audit-no-degree-budget", "analysis/order_conditions.py",
       "if max_degree is not None and deg > max_degree:", "if False:",
       "no degree budget for the exact decision: ten square roots (degree 1024) hang in sympy",
       "conditions", T + "test_ten_radicals_decide_numerically_without_hanging", TPREC),
    _m("audit-no-time-budget", "analysis/order_conditions.py",
       "                    raise ExactBudgetExceeded()", "                    pass",
       "the exact decision's time budget never enforced", "conditions",
       T + "test_exact_time_budget_falls_back_to_numerics_and_says_so", TPREC),
    _m("audit-zero-denominator-structural", "core/numbers.py",
       "if isinstance(node.op, ast.Div) and self.zero(b, node.right):",
       "if isinstance(node.op, ast.Div) and b == 0:",
       "an exact zero denominator that sympy does not reduce (sin(1)**2 + cos(1)**2 - 1) accepted",
       "conditions", TPREC + "::test_exact_zero_denominator_is_an_input_error", TPREC),
    _m("audit-disagreement-silent", "lab/theory/audit.py",
       "        if d:\n            parts.append(d)", "        if False:\n            parts.append(d)",
       "the verdict keeps silent when (22) and the numerical Theorem 1 check disagree", "conditions",
       T + "test_disagreement_between_22_and_theorem1_is_named", TPREC),
    _m("audit-theorem1-entry-tol-skipped", "lab/theory/audit.py",
       "    if tol_num > TEETH:\n", "    if tol > TEETH:\n",
       "a Theorem 1 tolerance widened by the entries' own precision counted as 'not decided' (a "
       "6-digit tableau exits 1 with 'too few scenes')", "theorem1",
       T + "test_six_digit_entries_theorem1_decided_to_their_precision", TPREC),
    _m("audit-theorem1-no-entry-tol", "lab/theory/audit.py",
       "        return ENTRY_TOL_FACTOR * max((c.residual or 0.0) for c in cs)", "        return 0.0",
       "Theorem 1 checked as if the entries satisfied (22) exactly (their residual in (22) ignored)",
       "theorem1", T + "test_six_digit_entries_theorem1_decided_to_their_precision", TPREC),
    _m("audit-ball-digits-working-only", "analysis/order_conditions.py",
       "    return max(2 * dps, (tab.decimal_digits or 0) + 20, 40)", "    return dps",
       "numerical decisions at the working dps (30) only: 40-digit entries decided below their "
       "precision, exact entries to 30 digits", "conditions",
       T + "test_22_pair_solved_at_40_digits_passes_and_a_1e10_change_fails_with_its_residual", TPREC),
)
