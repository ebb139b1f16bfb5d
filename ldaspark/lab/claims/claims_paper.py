"""Claims-ledger group for the paper's sections 2.2, 4, 5 and 7 (registered in
``ledger.CLAIM_GROUPS``): Definition 1 along trajectories (15a, 15b), the exact discrete
quantities of section 5 (16, 18, 17, 19, 20, 4.1 anti-symmetries, 5.1), the variational order,
the energy balance of 2.2 and the section 7 reductions. Each claim has at least one negative
control record (expected: fail). ``quick`` keeps one configuration per claim (~15 s); the full
group runs in ~60 s. The computations live in ``definition1``, ``section5``, ``variational``,
``energy_balance`` and ``section7``; the tests in ``verification/`` use the same functions."""
from __future__ import annotations

import math
import time

import mpmath

from ...core.families import get_method
from ...models.scenes import get_scene
from ..theory.definition1 import definition1_residuals
from ..theory.energy_balance import discrete_balance, exact_balance, predicted_mismatch_order
from .ledger import negative_controls, record
from ..theory.section5 import antisymmetry, exact_del, exact_identities, holonomic_exact
from ..theory.section7 import one_newton_iteration, reduction
from ..theory.variational import predicted_local_order, variational_errors

TOL_15A, TOL_15B, TOL_EXACT, TOL_S7, NEG = 1e-25, 1e-40, 1e-22, 1e-35, 1e-6
OFF_CD = ("1/1000", "-2/1000", "1/1000")


def _st(res, tol, expected="pass"):
    if expected == "pass":
        return "pass" if res is not None and res <= tol else "fail"
    return "fail" if res is not None and res >= NEG else "pass"


def _timed(fn, *a, **k):
    t = time.time()
    out = fn(*a, **k)
    return out, time.time() - t


def definition1_records(quick):
    out = []
    runs = [("euler-ii", "particle")] if quick else [("gauss-2", "particle"), ("lobatto-iiia-iiib-2", "particle"),
                                                     ("euler-ii", "particle")]
    for name, scn in runs:
        sc = get_scene(scn)
        t0, q0, v0 = sc.initial(60)
        r = definition1_residuals(sc.system, get_method(name, exact=True), t0, q0, v0, "0.1", n_steps=10, dps=30)
        note = (f"N = 10, h = 0.1, FD of the endpoint solve at 50 digits; force-free sum "
                f"{r['15a_without_forces']:.1e}; secant-velocity c {r['15b_secant']:.1e}")
        out.append(record("15a", name, scn, _st(r["15a"], TOL_15A), r["15a"], "pass", 30, r["wellposed"],
                          r["seconds"] / 2, "ivp-10-steps", TOL_15A, note))
        out.append(record("15b", name, scn, _st(r["15b"], TOL_15B), r["15b"], "pass", 30, r["wellposed"],
                          r["seconds"] / 2, "ivp-10-steps", TOL_15B, note))
    # off C_d (inconsistent data, v0[0] + 1/10) on a time-dependent scene: (15b) is k at the
    # right end point (0 by (21f)); the left end point is not 0 on the first step (control)
    sc = get_scene("rheonomic-skate")
    t0, q0, v0 = sc.initial(60)
    v0 = [v0[0] + mpmath.mpf(1) / 10] + list(v0[1:])
    r = definition1_residuals(sc.system, get_method("gauss-2", exact=True), t0, q0, v0, "0.1", n_steps=3, dps=20)
    out.append(record("15b", "gauss-2", "rheonomic-skate", _st(r["15b"], 1e-30), r["15b"], "pass", 20, r["wellposed"],
                      r["seconds"], "off-C_d-3-steps", 1e-30, f"k(t0, q0, v0) != 0 initially; (15a) {r['15a']:.1e}"))
    out.append(record("15b", "gauss-2 (control: left end point)", "rheonomic-skate",
                      _st(r["15b_left_end"], NEG, "fail"), r["15b_left_end"], "fail", 20, r["wellposed"], 0,
                      "off-C_d-3-steps", NEG, "c = k(t_k, q_k, v0) at the left end point is not 0 off C_d"))
    tab, _ = negative_controls()[0]
    sc = get_scene("particle")
    t0, q0, v0 = sc.initial(60)
    r = definition1_residuals(sc.system, tab, t0, q0, v0, "0.1", n_steps=3, dps=20)
    out.append(record("15a", tab.name, "particle", _st(r["15a"], NEG, "fail"), r["15a"], "fail", 20,
                      r["wellposed"], r["seconds"], "ivp-3-steps", NEG, "(22b) broken: negative control"))
    return out


def section5_records(quick):
    out = []
    # the rheonomic skate (L and k depend on t) is the fixture that sees a time argument shifted
    # by h; the paper scenes are autonomous
    for scn in (("particle", "rheonomic-skate") if quick else ("particle", "skate", "rheonomic-skate")):
        r, sec = _timed(exact_identities, scn, offset=OFF_CD)
        pt = "off-C_d"
        note = f"FD at 52 digits; |f_d^E-| = {r['f_d_minus']:.2e}, k0 = {r['k0']:.1e}"
        for claim, key, ctl in (("16", "16", "16-without-force"), ("18", "18", "18-without-force")):
            out.append(record(claim, "exact-flow", scn, _st(r[key], TOL_EXACT), r[key], "pass", 32, "n/a", sec / 4,
                              pt, TOL_EXACT, note))
            out.append(record(claim, "exact-flow (control: no force)", scn, _st(r[ctl], NEG, "fail"), r[ctl], "fail",
                              32, "n/a", 0, pt, NEG, "dL_d^E/dq against the bare momentum"))
        out.append(record("17-integral", "exact-flow", scn, _st(r["17"], TOL_EXACT), r["17"], "pass", 32, "n/a",
                          sec / 4, pt, TOL_EXACT, "(17) double integral vs (12a)"))
        out.append(record("17-integral", "exact-flow (control: inner int_s^t1)", scn,
                          _st(r["17-other-inner"], NEG, "fail"), r["17-other-inner"], "fail", 32, "n/a", 0, pt, NEG,
                          "(17) with the inner integral over [s, t1] instead of [t0, s], vs (12a)"))
        out.append(record("19-integral", "exact-flow", scn, _st(r["19"], TOL_EXACT), r["19"], "pass", 32, "n/a",
                          sec / 4, pt, TOL_EXACT, "(19) double integral vs (12b)"))
        out.append(record("19-integral", "exact-flow (control: inner int_t0^s)", scn,
                          _st(r["19-other-inner"], NEG, "fail"), r["19-other-inner"], "fail", 32, "n/a", 0, pt, NEG,
                          "(19) with the inner integral over [t0, s] instead of [s, t1], vs (12b)"))
        out.append(record("20-integral", "exact-flow (printed 20b)", scn, _st(r["20b-printed"], NEG, "fail"),
                          r["20b-printed"], "fail", 32, "n/a", 0, pt, NEG,
                          "printed inner limits int_s^{t_k} give -f_d^{E-} (sign slip)"))
    if quick:       # (20b) read int_{t_k}^s against (12a) on one interval
        r = exact_identities("particle", offset=OFF_CD)
        out.append(record("20-integral", "exact-flow", "particle", _st(r["20b-corrected"], TOL_EXACT),
                          r["20b-corrected"], "pass", 32, "n/a", 0, "off-C_d", TOL_EXACT,
                          "(20b) with inner integral int_{t_k}^s vs (12a)"))
    else:
        for scn in ("particle", "rheonomic-skate"):
            r, sec = _timed(exact_del, scn)
            out.append(record("20-integral", "exact-flow", scn, _st(r["del"], TOL_EXACT), r["del"], "pass", 32,
                              "n/a", sec, "exact-2-steps", TOL_EXACT,
                              f"exact discrete EL with (20a), (20b) read int_{{t_k}}^s; printed (20b) "
                              f"{r['del-printed-20b']:.1e}; momentum continuity {r['momentum-continuity']:.1e}"))
    for scn in ("particle", "rheonomic-skate"):
        r, sec = _timed(antisymmetry, scn, offset=OFF_CD)
        res = max(r["L"], r["f_plus"], r["f_minus"])
        out.append(record("antisymmetry-exact", "exact-flow", scn, _st(res, TOL_EXACT), res, "pass", 32, "n/a", sec,
                          "off-C_d", TOL_EXACT, "L_d^E, f_d^E+, f_d^E- under exchange of the endpoints (4.1)"))
        out.append(record("antisymmetry-exact", "exact-flow (control: wrong pairing)", scn,
                          _st(r["wrong-pairing"], NEG, "fail"), r["wrong-pairing"], "fail", 32, "n/a", 0, "off-C_d",
                          NEG, "f_d^E+(rev) + f_d^E+(fwd)"))
    for scn, exp in (("pendulum", "pass"), ("particle", "fail")):
        r, sec = _timed(holonomic_exact, scn, offset=("1/1000", "-1/1000") if scn == "pendulum" else None)
        out.append(record("5.1-exact", "exact-flow", scn, _st(r["tangential"], 1e-28, exp), r["tangential"], exp, 32,
                          "n/a", sec, "h=0.1", 1e-28 if exp == "pass" else NEG,
                          f"f_d^E+- on tangent variations; full covector {r['full']:.1e}"
                          + ("" if exp == "pass" else " (nonholonomic control)")))
    return out


# Two-sided order checks: |observed - predicted| <= tol with tol < 1/2, so that a prediction
# off by one in either direction fails on the data where the right one passes
# (|observed - (p +- 1)| >= 1 - tol > tol). Measured (h = 0.2, 0.1, 0.05 on the skate, 24 digits):
# Gauss-1 2.96 (p = 3), Gauss-2 4.82 (p = 5): worst gap 0.18, tol 0.4.
TOL_VARIATIONAL = 0.4
# energy balance 2.2, one-step h-sweep 0.1, 0.05, 0.025 (the last pair decides): Gauss-1 2.96
# (p + 1 = 3), Gauss-2 5.02 (5), Lobatto IIIA-B 2 3.0 (3), Euler I 2.35 (2; pre-asymptotic: 2.51 at
# 0.2/0.1 and 2.22 at 0.025/0.0125, approaching 2 from above): worst gap 0.35, tol 0.4
TOL_ENERGY_ORDER = 0.4
ENERGY_HS = ("0.1", "0.05", "0.025")


def variational_records(quick):
    """|L_d - L_d^E| ~ h^{r+1} (``variational.predicted_local_order``), two-sided; the control
    (Gauss-2 with (22b) broken) is judged against the unperturbed Gauss-2's prediction."""
    out = []
    tabs = [get_method("gauss-1", exact=True)] + ([] if quick else [get_method("gauss-2", exact=True)])
    tabs.append(negative_controls()[0][0])      # the control, in the quick run too (~1 s)
    # the rheonomic skate (L and k depend on t) sees a time argument off by h; measured 2.92 for
    # Gauss-1 (prediction 3)
    runs = [(tab, "skate") for tab in tabs] + [(tabs[0], "rheonomic-skate")]
    for tab, scn in runs:
        r, sec = _timed(variational_errors, tab, scn, dps=24, stages=8)
        o = r["orders"]["L_d"]
        control = tab.name.startswith("negctl")
        pred = predicted_local_order(get_method("gauss-2", exact=True)) if control else r["predicted_local_order"]
        gap = None if o is None or o == math.inf else abs(o - pred)
        st = "pass" if gap is not None and gap <= TOL_VARIATIONAL else "fail"
        note = (f"|L_d - L_d^E| order {o:.2f} (global order {r['global_order']}, variational prediction {pred}); "
                f"f_d^- order {r['orders']['f_minus']}, tangential {r['orders']['f_minus_tangential']}; "
                f"h = {r['h']}")
        out.append(record("variational-order", tab.name, scn, st, gap, "fail" if control else "pass", 24, "n/a",
                          sec, "perturbed-ivp", TOL_VARIATIONAL, note))
    return out


def energy_records(quick):
    """Exact balance of 2.2 (pointwise and integrated, with controls) and the discrete one:
    Delta E - quadrature ~ h^{p+1} (``energy_balance.predicted_mismatch_order``), two-sided."""
    out = []
    for name, ctl in (("time-L", "without_L_t"), ("affine-b", "without_psi_term")):
        r, sec = _timed(exact_balance, name, dps=28, stages=8)
        res = max(r["pointwise"], r["integral"])
        out.append(record("energy-balance-2.2", "exact-flow", name, _st(res, TOL_EXACT), res, "pass", 28, "n/a", sec,
                          "h=0.1", TOL_EXACT, f"Delta E = {r['delta_E']:.2e} (not conserved)"))
        out.append(record("energy-balance-2.2", f"exact-flow (control: {ctl})", name, _st(r[ctl], NEG, "fail"),
                          r[ctl], "fail", 28, "n/a", 0, "h=0.1", NEG, "the dropped term is what changes E"))
    for m in (("gauss-2",) if quick else ("gauss-1", "gauss-2", "lobatto-iiia-iiib-2", "euler-i")):
        tab = get_method(m, exact=True)
        r, sec = _timed(discrete_balance, "time-L", tab, hs=ENERGY_HS)
        pred = predicted_mismatch_order(tab)
        o = r["order_mismatch"]
        gap = None if o is None else abs(o - pred)
        c = discrete_balance("particle", tab, hs=ENERGY_HS)
        out.append(record("energy-balance-2.2", m, "time-L",
                          "pass" if gap is not None and gap <= TOL_ENERGY_ORDER else "fail", gap, "pass", 30,
                          "n/a", sec, "one-step h-sweep", TOL_ENERGY_ORDER,
                          f"Delta E - quadrature ~ h^{_f2(o)} (p+1 = {pred}); Delta E ~ "
                          f"h^{_f2(r['order_delta_E'])}; conservative particle: Delta E ~ h^{_f2(c['order_delta_E'])}"))
    return out


def _f2(x):
    return "-" if x is None else f"{x:.2f}"


def section7_records(quick):
    out = []
    for claim, kind, name, exp in (("euler-i-reduction", "euler-i", "euler-i", "pass"),
                                   ("euler-ii-reduction", "euler-ii", "euler-ii", "pass"),
                                   ("midpoint-7.3", "midpoint", "gauss-1", "pass"),
                                   ("euler-i-reduction", "euler-i", "euler-ii", "fail"),
                                   ("euler-ii-reduction", "euler-ii", "euler-i", "fail"),
                                   ("midpoint-7.3", "midpoint", "lobatto-iiia-iiib-2", "fail")):
        r, sec = _timed(reduction, kind, get_method(name, exact=True), constant_K=False)
        res = max(r["diff"], r["stage"]) if exp == "pass" else r["diff"]
        out.append(record(claim, name, "affine-K(q)", _st(res, TOL_S7, exp), res, exp, 40, "n/a", sec, "h=0.1",
                          TOL_S7 if exp == "pass" else NEG,
                          f"SPARK step vs the printed {kind} system solved on its own; stage statement {r['stage']:.1e}"))
    for name, ck, guess, exp in (("euler-i", True, "generic", "pass"), ("euler-ii", False, "default", "pass"),
                                 ("euler-i", False, "generic", "fail")):
        r, sec = _timed(one_newton_iteration, get_method(name, exact=True), ck, guess)
        out.append(record("linearly-implicit-7", name, "affine-const-K" if ck else "affine-K(q)",
                          _st(r["after_one"], TOL_S7, exp), r["after_one"], exp, 40, "n/a", sec, f"start {guess}",
                          TOL_S7 if exp == "pass" else NEG, "|G| after one Newton iteration on (21)"))
    return out


_PARTS = (("definition-1", definition1_records), ("section-5", section5_records),
          ("variational-order", variational_records), ("energy-2.2", energy_records),
          ("section-7", section7_records))
# CPU seconds per part on an idle core (scheduling only), measured on the full run
_PART_COST = {"definition-1": 3.3, "section-5": 4.3, "variational-order": 3.1, "energy-2.2": 0.8, "section-7": 1.3}


def pieces(quick=False):
    """The independent parts of ``records`` in order (``ledger.group_pieces``)."""
    return [label for label, _ in _PARTS]


def piece_cost(piece):
    return _PART_COST.get(piece, 5.0)


def piece_records(piece, quick=False):
    return dict(_PARTS)[piece](quick)


def records(quick=False, progress=None):
    """All records of this group (see module docstring)."""
    out = []
    for i, (label, fn) in enumerate(_PARTS, 1):
        out += fn(quick)
        if progress:
            progress(i, len(_PARTS), "paper claims", label)
    return out
