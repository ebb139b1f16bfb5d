"""``ldaspark audit``: a new tableau against the hypotheses of Theorem 1 and the numerics.

    ldaspark audit FILE [--dps D] [--json OUT] [--out MD] [--quick]
    ldaspark audit --method NAME [...]

Checks (each a ``Check``: name, status pass/fail/info/skip, residual, detail):

* shapes, row sums sum_j a_ij = c_i of A, A_hat, A_tilde (information: Theorem 1 does not
  need them, Euler I has A_hat 1 = 1 != c = 0), the rank of omega in (21e);
* (22a), (22b) (hypotheses of Theorem 1) and (23a-d) (symmetry), like every algebraic check,
  decided at the precision the entries carry (``decide_arith``): exact in an algebraic number
  field when the entries are exact and the decision is cheap (degree bound, time budget), else
  in ball arithmetic on balls enclosing what the entries stand for (decimals to the digits given,
  float64 to half an ulp, exact entries to twice the working digits): a condition holds when its
  ball contains 0 and is violated only when it excludes 0 (docs/audit.md);
* tree conditions (order_conditions): A, A_hat, A_tilde as RK methods, the pair (A, A_hat)
  on bi-coloured trees, (A; A_hat, A_tilde) on the forced ODE (6) (the prediction), B/C/D,
  R(inf);
* Theorem 1 on the four paper scenes and the symmetry identities (ldaspark.analysis.discrete);
* whether (21) is solvable for small h: N = [omega A_tilde; b_tilde^T] nonsingular (explicit
  tableaux whose N is singular get that verdict, exit 1, and no numerical check);
* observed convergence order on the skate (exact solution) and the particle (reference by a
  different, higher-order Gauss SPARK method), the constraint residual, the energy error. The
  observed order (finest usable pair) must not lie more than ORDER_SLACK (0.45) below the
  prediction; above it is reported, not failed (one-sided).

Every numerical tolerance that the entries' own uncertainty enters (Theorem 1, symmetry, the
convergence floor) is measured on the scene: the check is evaluated on the tableau moved in the
shape of the entries' radii (``audit_checks.entry_effect``), not a fixed factor.

Exit code 0 when (22) holds and every numerical check agrees with the theory, 1 when a check
fails, 2 (LdasparkError) for unusable input.
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field

from ...analysis import order_conditions as oc
from .audit_checks import (FAIL, INFO, ORDER_SLACK, PASS, SKIP, Check, _coefficient_strings, _fmt, _jsonable,  # noqa: F401
                           check_22a, check_22b, check_23, check_23_omega, check_omega, check_solvable, check_omega_default, check_row_sums,
                           check_shapes, convergence_checks, digits_of, energy_check, entry_effect, entry_radii,
                           observed_order, order_checks, probe_step)
from ...core.errors import InputError, LdasparkError
from ...core.tableau import SparkTableau
from ...core.tableau_file import load_tableau
from ...core.families import get_method

PAPER_SCENES = ("particle", "skate", "robot", "mp-particles")


@dataclass
class AuditResult:
    tableau: str
    s: int
    exact: bool
    dps: int
    quick: bool
    checks: list = field(default_factory=list)
    facts: dict = field(default_factory=dict)
    verdict: str = ""
    seconds: float = 0.0

    @property
    def exit_code(self) -> int:
        return 1 if any(c.status == FAIL for c in self.checks) else 0

    def get(self, name) -> Check | None:
        return next((c for c in self.checks if c.name == name), None)

    def as_dict(self) -> dict:
        return {"tableau": self.tableau, "s": self.s, "exact": self.exact, "dps": self.dps,
                "quick": self.quick, "exit_code": self.exit_code, "verdict": self.verdict,
                "facts": _jsonable(self.facts), "seconds": round(self.seconds, 2),
                "checks": [c.as_dict() for c in self.checks]}


# --- Theorem 1 -------------------------------------------------------------------------------
def theorem1_checks(tab, hyp22, hyp23, dps, quick, scenes=PAPER_SCENES, entry_tol=None):
    """Theorem 1 and the symmetry identities on the four paper scenes, via ldaspark.analysis.discrete.
    ``entry_tol`` = (for Theorem 1, for the symmetry identities): how far the entries as
    given miss (22), (23) (``entry_tolerances``); None: from ``tab.source_digits``. Returns (checks, facts)."""
    import importlib.util
    if importlib.util.find_spec("ldaspark.analysis.discrete") is None:
        return [Check("theorem1", SKIP, None, "ldaspark.analysis.discrete is not available: "
                                              "Theorem 1 not checked numerically")], {}
    return _theorem1_with_discrete(tab, hyp22, hyp23, dps, quick, scenes, entry_tol)


TEETH = 1e-6        # a Theorem 1 tolerance above this could not tell (22) from its violation
#: how a scene left undecided by the entries' digits begins (``_theorem1_scene``, ``_theorem1_summary``)
ENTRY_UNDECIDED = "not decided: what the entries' uncertainty can contribute"
THEOREM_H = "1/10"   # step of the base point (t0, q0) -> (t1, q1) for Theorem 1 and symmetry
#: kept for the gate of ``entry_tolerances`` (nonzero: (22), resp. (23), holds only to the
#: precision the entries carry); the allowance itself is measured per scene (``entry_effect``)
ENTRY_TOL_FACTOR = 1e3


def _theorem1_tol(tab, dps, fd_error, entry_tol=None):
    """Relative tolerance of the numerical Theorem 1 and symmetry identities: above the
    finite-difference error estimate and the working precision (and ``entry_tol`` when given).
    What the entries' own uncertainty contributes is measured separately (``entry_effect``)."""
    return max(10 * fd_error, 10.0 ** (-dps / 2), entry_tol or 0.0)


def entry_tolerances(checks) -> tuple[float, float]:
    """The gates of the entries' allowance (for Theorem 1, for the symmetry identities):
    ENTRY_TOL_FACTOR times the largest residual of (22a, b), resp. (23a-d), of the entries as given
    when those hold to the entries' precision (exact decisions: 0); 0 when they are violated, so
    that a violation is seen at full strength. Nonzero opens the measured allowance
    (``entry_effect``) of each scene."""
    def tol(names):
        cs = [c for c in checks if c.name in names]
        if not cs or any(c.status != PASS for c in cs):
            return 0.0
        return ENTRY_TOL_FACTOR * max((c.residual or 0.0) for c in cs)
    return tol(("22a", "22b")), tol(("23a", "23b", "23c", "23d"))


def _theorem1_with_discrete(tab, hyp22, hyp23, dps, quick, scenes, entry_tol=None):
    """Theorem 1 per scene, its summary, then the symmetry identities under (23)."""
    checks, facts = [], {}
    tol22, tol23 = entry_tol if entry_tol is not None else (None, None)
    for name in scenes:
        check, fact = _theorem1_scene(tab, name, hyp22, dps, quick, tol22)
        checks.append(check)
        if fact is not None:
            facts[f"theorem1:{name}"] = fact
    checks.append(_theorem1_summary(checks))
    if hyp23:
        sym_scenes = [x for x in scenes if x in ("skate", "particle")] if quick else scenes
        sym_checks, sym_facts = _symmetry_checks(tab, dps, sym_scenes, tol23)
        checks += sym_checks
        facts.update(sym_facts)
    else:
        checks.append(Check("symmetry", SKIP, None, "(23) does not hold: Theorem 1 claims no symmetry"))
    return checks, facts


def _theorem1_scene(tab, name, hyp22, d, quick, entry_tol=None):
    """One scene's Theorem 1 check (dL_d/dq0 = -p0 - f_d^-, dL_d/dq1 = p1 - f_d^+) and its facts."""
    from ...analysis import discrete, wellposedness
    from ...models.scenes import get_scene
    sc = get_scene(name)
    t0, q0, v0 = sc.initial(d + 45)
    r, err = None, None
    # an ill-conditioned BVP (tiny sigma_min) can stall Newton at the precision floor or
    # make the finite differences too coarse: the full audit retries once at +20 digits
    for dd in (d,) if quick else (d, d + 20):
        try:
            r = discrete.theorem1_residuals(sc.system, tab, t0, q0, v0, THEOREM_H, dps=dd)
            err = None
        except LdasparkError as exc:
            r, err = None, str(exc).splitlines()[0]
            continue
        if _theorem1_tol(tab, dd, r["fd_error"], 0.0) <= TEETH:
            break
    if r is None:
        return Check(f"theorem1:{name}", SKIP, None,
                     f"not decided: boundary-value solve of (21) failed ({err}) at dps "
                     f"{d}{'' if quick else f' and {d + 20}'}; the implicit functions of Theorem 1 "
                     "are not established numerically here"), None
    wp = r["wellposed"]
    if not quick:
        try:
            wpc = wellposedness.classify_wellposedness(sc.system, tab, t0, q0, v0, THEOREM_H, dps=(d, d + 20))
            wp = f"{wpc['class']} (rank deficiency {wpc['rank_deficiency']}, decided at dps {d}, {d + 20} and h, h/2)"
            if "entries_undecided" in wpc:     # a sigma the entries' digits cannot tell from zero
                u = wpc["entries_undecided"]
                wp = (f"rank not decided at the precision of the entries ({u['reason']}; "
                      f"{u['class_if_zero']} if it is zero; rank deficiency {wpc['rank_deficiency']} at dps {d}, {d + 20})")
        except LdasparkError as exc:
            wp = f"{wp} (classification failed: {exc})"
    else:
        wp = f"{wp} (rank deficiency {r['rank_deficiency']} at dps {r['dps_fd']})"
        if "entries_undecided" in r:       # a sigma the entries' digits cannot tell from zero
            wp += f": rank not decided at the precision of the entries ({r['entries_undecided']['reason']})"
    if r.get("rank_at_entries_precision"):
        # the solve without the gauge border failed: its zeros were taken at the entries' precision
        wp += (f"; the finite-difference solves took singular values below "
               f"{discrete.ENTRY_RANK_FACTOR:.0e} x the entries' relative uncertainty as zero")
    res = max(r["theorem1-q0"], r["theorem1-q1"])
    # the numerical part of the tolerance (finite differences, working precision) must have teeth
    tol_num = _theorem1_tol(tab, r["dps"], r["fd_error"], 0.0)
    tol, ent = tol_num, None
    if res > tol_num and (entry_tol is None or entry_tol > 0):
        # (22) holds to the precision the entries carry, not exactly: what that uncertainty can
        # contribute on this scene is measured (``entry_effect``: the residual of the tableau moved
        # in the shape of the entries' radii); a residual within it is the sharpest check these
        # entries allow, decided against it and said so
        radii = entry_radii(tab)
        if radii is not None:
            try:
                ent = entry_effect(tab, radii, lambda T: _theorem1_residual(sc, T, t0, q0, v0, r["dps"]))
                tol = max(tol_num, ent[0])
            except LdasparkError:      # a moved tableau's BVP failed: no allowance, full strength
                ent = None
    ok = res <= tol
    claim = ("agrees with Theorem 1" if hyp22 else
             "holds although (22) fails" if ok else "fails, as expected without (22)")
    status = PASS if ok else FAIL
    forces = r.get("without_forces_q0")
    if tol_num > TEETH:
        status, claim = SKIP, f"not decided (tolerance {tol_num:.0e} above {TEETH:.0e} at dps {r['dps']})"
    elif ent is not None and tol > tol_num and forces is not None and tol >= forces:
        # the entries' allowance is as large as what the forces f_d contribute (the residual of the
        # claim without them): a pass could not tell Theorem 1 from its claim without f_d
        status, claim = SKIP, (f"{ENTRY_UNDECIDED} on this scene, "
                               f"{tol:.0e} (a response of {ent[1]:.1e} per unit change, measured), is not below "
                               f"what the forces f_d contribute, {forces:.1e} (the residual without them); "
                               f"more digits in the file would decide it (residual {res:.1e})")
    elif ent is not None and res > tol_num:
        claim += (f" to the precision of the entries: holds to {digits_of(res)} digits (residual {res:.1e}, "
                  f"within {tol:.0e}, what the entries' uncertainty can contribute on this scene: a response "
                  f"of {ent[1]:.1e} per unit change of the entries, measured; no sharper check is possible "
                  "with these entries)")
    check = Check(
        f"theorem1:{name}", status, res,
        f"{claim}: |dL_d/dq0 + p0 + f_d^-|, |dL_d/dq1 - p1 + f_d^+| relative = "
        f"{r['theorem1-q0']:.1e}, {r['theorem1-q1']:.1e} (tolerance {tol:.0e}; FD error {r['fd_error']:.0e}; "
        f"without the forces {r['without_forces_q0']:.1e}); h = {THEOREM_H}, dps {r['dps']}; BVP {wp}",
        tolerance=tol)
    return check, {k: v for k, v in r.items() if k != "null_support"}


def _theorem1_residual(sc, T, t0, q0, v0, dps) -> float:
    """Theorem 1's residual on one scene for the tableau T (``entry_effect``)."""
    from ...analysis import discrete
    r = discrete.theorem1_residuals(sc.system, T, t0, q0, v0, THEOREM_H, dps=dps)
    return max(r["theorem1-q0"], r["theorem1-q1"])


def _theorem1_summary(checks):
    """Theorem 1 overall: decided on at least two scenes (or all, if fewer), none failing."""
    th = [c for c in checks if c.name.startswith("theorem1:")]
    decided = [c for c in th if c.status != SKIP]
    nfail = sum(c.status == FAIL for c in decided)
    need = min(2, len(th))
    limited = [c for c in th if c.status == SKIP and c.detail.startswith(ENTRY_UNDECIDED)]
    if len(decided) < need and limited and len(limited) == len(th) - len(decided) and not nfail:
        # every scene left undecided is undecided by the entries' digits (not by a failed solve): the
        # digits given cannot decide Theorem 1 numerically, which is no failure of the tableau
        # fewer decided scenes than needed (need <= 2): at most one, its residual
        return Check("theorem1", INFO, (decided[0].residual or 0.0) if decided else None,
                     f"not decided at the precision of the entries: decided on {len(decided)} of {len(th)} scenes "
                     f"(at least {need} needed); on {', '.join(c.name.split(':', 1)[1] for c in limited)} the entries' "
                     "uncertainty can contribute as much as the forces f_d (more digits in the file would decide it)")
    if len(decided) < need:
        return Check("theorem1", FAIL, None, f"decided on only {len(decided)} of {len(th)} scenes "
                                             f"(at least {need} needed)")
    return Check("theorem1", FAIL if nfail else PASS, max((c.residual or 0.0) for c in decided),
                 f"decided on {len(decided)} of {len(th)} scenes, {nfail} failing")


def _symmetry_checks(tab, d, scenes, entry_tol=None):
    """The (23) symmetry identities per scene and their summary."""
    from ...analysis import symmetry
    from ...models.scenes import get_scene
    checks, facts = [], {}
    keys = ("symmetry-Ld", "symmetry-fd-plus", "symmetry-fd-minus", "symmetry-Phi")
    for name in scenes:
        sc = get_scene(name)
        t0, q0, v0 = sc.initial(d + 5)
        try:
            r = symmetry.check_symmetry(sc.system, tab, t0, q0, v0, THEOREM_H, dps=d)
        except LdasparkError as exc:
            checks.append(Check(f"symmetry:{name}", SKIP, None,
                                f"not decided: forward/reverse BVP solve failed ({str(exc).splitlines()[0]})"))
            continue
        # With a singular (non-gauge) BVP Jacobian the implicit functions of Theorem 1 are
        # not unique, so f_d^+- (built from dV/dq) depend on the gauge fixing: only L_d and
        # the map Phi_h are then decidable; the f_d parts are reported, not judged.
        judged = keys if r["wellposed"] != "singular" else ("symmetry-Ld", "symmetry-Phi")
        res = max(r[k] for k in judged)
        tol = tol_num = _theorem1_tol(tab, d, 0.0, 0.0)
        held = ""
        if res > tol_num and (entry_tol is None or entry_tol > 0):
            # (23) holds to the entries' precision only: their uncertainty's effect, measured
            radii = entry_radii(tab)
            try:
                bound, per = (entry_effect(tab, radii, lambda T: _symmetry_residual(sc, T, t0, q0, v0, d, judged))
                              if radii is not None else (0.0, 0.0))
            except LdasparkError:      # a moved tableau's solve failed: no allowance, full strength
                radii = None
            if radii is not None:
                tol = max(tol_num, bound)
                held = (f"; holds to {digits_of(res)} digits, the precision of the entries (their uncertainty "
                        f"can contribute {bound:.0e} here: response {per:.1e} per unit change, measured)")
        facts[f"symmetry:{name}"] = {k: v for k, v in r.items() if isinstance(v, (int, float, str))}
        note = "" if judged == keys else "; f_d parts not judged: BVP singular, f_d not unique"
        if r.get("rank_at_entries_precision"):
            note += (f"; J's sigma_min taken as zero: {r['entries_undecided']['reason']}")
        if tol > max(tol_num, TEETH):
            # an allowance above TEETH cannot tell (23) from its violation (a non-symmetric method of
            # order p misses the identities by O(h^(p+1)), 1e-5 at order 4 and h = 1/10); 10-digit Lobatto
            # IIIA-IIIB 3 passed here at 3e+02 (a response of 1e10 per unit change: the moved tableau's
            # BVP is of another class)
            checks.append(Check(
                f"symmetry:{name}", SKIP, res,
                f"{ENTRY_UNDECIDED} on this scene, {tol:.0e}, is above {TEETH:.0e}: it could not tell (23) from "
                f"its violation (residual {res:.1e}; BVP {r['wellposed']}{note}); more digits in the file would "
                "decide it", tolerance=tol))
            continue
        checks.append(Check(
            f"symmetry:{name}", PASS if res <= tol else FAIL, res,
            "L_d(t1,q1,t0,q0) + L_d, f_d^+(rev) + f_d^-, f_d^-(rev) + f_d^+, Phi_-h(Phi_h(y)) - y: "
            + ", ".join(f"{r[k]:.1e}" for k in keys) + f" (tolerance {tol:.0e}; BVP {r['wellposed']}{note}){held}",
            tolerance=tol))
    dec = [c for c in checks if c.status != SKIP]
    if checks and not dec and all(c.detail.startswith(ENTRY_UNDECIDED) for c in checks):
        # undecided by the entries' digits on every scene (not by a failed solve): no failure of the tableau
        checks.append(Check("symmetry", INFO, None, f"not decided at the precision of the entries on any of "
                            f"{len(checks)} scenes (more digits in the file would decide it)"))
    elif checks:
        nf = sum(c.status == FAIL for c in dec)
        checks.append(Check("symmetry", FAIL if (nf or not dec) else PASS,
                            max([(c.residual or 0.0) for c in dec] or [0.0]),
                            f"decided on {len(dec)} of {len(checks)} scenes, {nf} failing"
                            + ("" if dec else " (at least one needed)")))
    return checks, facts


def _symmetry_residual(sc, T, t0, q0, v0, dps, keys) -> float:
    """The judged symmetry identities' residual on one scene for the tableau T (``entry_effect``)."""
    from ...analysis import symmetry
    r = symmetry.check_symmetry(sc.system, T, t0, q0, v0, THEOREM_H, dps=dps)
    return max(r[k] for k in keys)


# --- the audit -------------------------------------------------------------------------------
def predicted_order(tab, facts) -> int:
    """The order the conditions predict: the forced-ODE order (3-coloured trees)."""
    return int(facts["order:forced-ode"])


def decide_arith(tab: SparkTableau, dps: int, arith: str = "auto", exact_seconds: float | None = None):
    """The arithmetic of the algebraic checks: (Arith, entries, reason). ``auto``: exact when the
    entries are known exactly (no decimal literal, no float64) and the exact decision is cheap
    (``oc.exact_budget``: algebraic entries, number field degree <= EXACT_MAX_DEGREE; the
    deadline ``exact_seconds`` guards the rest), else arb balls at ``oc.ball_digits`` digits on
    what the entries stand for. ``exact``: exact, decimals read as exact rationals (InputError for
    float64 or transcendental entries). ``mp``: balls, whatever the entries."""
    import time as _time
    if exact_seconds is None:
        exact_seconds = EXACT_FORCED_SECONDS if arith == "exact" else oc.EXACT_SECONDS
    if arith == "exact":
        if not tab.is_exact:
            raise InputError(f"tableau {tab.name} has inexact entries: --arith exact is not possible")
        ok, why = oc.exact_budget(tab, max_degree=EXACT_FORCED_MAX_DEGREE)
        reason = ("exact by request (--arith exact)" + ("; decimal literals read as exact rationals, "
                  "not as the digits given" if tab.decimal_digits else "")) if ok else \
            f"--arith exact was asked for, but {why}"
    elif arith == "auto" and tab.known_exactly:
        ok, why = oc.exact_budget(tab)
        reason = f"the entries are exact and the decision is cheap ({why})" if ok else why
    else:
        ok = False
        reason = ("numerical by request (--arith mp)" if arith == "mp" else
                  f"the entries carry {tab.precision_text()}")
    if ok:
        ar, e = oc.exact_arith(tab)
        if oc._decidable(ar.K):
            ar.deadline = _time.monotonic() + exact_seconds
            return ar, e, reason
        ok, reason = False, f"sympy puts the entries in {ar.K}, where equality is not decidable exactly"
    return _ball(tab, dps, reason) + (reason,)


#: an exact decision asked for with --arith exact: a larger field than auto allows (Gauss-4: bound
#: 32), still bounded so that sympy's primitive element cannot run for hours
EXACT_FORCED_MAX_DEGREE = 64
#: and a longer time budget (the tree conditions of Gauss-4 take ~30 s exactly)
EXACT_FORCED_SECONDS = 120.0


def _ball(tab, dps, reason):
    """Ball arithmetic for ``tab`` at ``oc.ball_digits`` digits, labelled with ``reason``."""
    return oc.ball_arith(tab, oc.ball_digits(tab, dps), reason)


def algebraic_checks(tab, ar, e, dps):
    """Every check on the coefficients alone, in the arithmetic ``ar``. Returns (checks, facts)."""
    C, facts = [], {}
    C.append(check_shapes(tab))
    for M in ("A", "A_hat", "A_tilde"):
        C.append(check_row_sums(ar, e, M))
    C.append(check_omega(tab, ar, e, dps))
    C.append(check_omega_default(tab, dps))
    C.append(check_solvable(tab))
    C.append(check_22a(ar, e))
    C.append(check_22b(ar, e))
    C.extend(check_23(ar, e))
    facts["22"] = C[-6].status == PASS and C[-5].status == PASS
    facts["23"] = all(c.status == PASS for c in C[-4:])
    # (23a-d) make the method symmetric only when omega's rows are closed under reversal
    C.append(check_23_omega(tab))
    facts["23"] = facts["23"] and C[-1].status == PASS
    chk, f = order_checks(ar, e)
    C.extend(chk)
    facts.update(f)
    p = predicted_order(tab, facts)
    facts["predicted_order"] = p
    how = "exactly" if ar.exact else f"to {ar.scope}"
    C.append(Check("consistent", PASS if p >= 1 else FAIL, None,
                   f"the conditions predict order {p} ({how})" + (
                       " >= 1: the method converges" if p >= 1 else
                       ": sum b != 1 or similar by more than the entries' precision, the method cannot converge"
                       + ("" if ar.exact else
                          " (decimal entries are read as rounded, known to half a unit in their last digit: "
                          "digits printed by truncation are off by up to a whole unit; give them rounded or "
                          "with more digits)")),
                   ar.label))
    return C, facts


def audit(tab: SparkTableau, dps: int = 30, quick: bool = False, arith: str = "auto",
          progress=None, theorem_scenes=PAPER_SCENES, exact_seconds: float | None = None) -> AuditResult:
    """Run every check on ``tab``; see the module docstring. ``theorem_scenes`` restricts the
    Theorem 1 scenes (the CLI always uses the four paper scenes; tests use fewer);
    ``exact_seconds`` the time budget of an exact decision (default oc.EXACT_SECONDS)."""
    t_start = time.time()
    _say = progress or (lambda msg: None)
    say = lambda msg: _say(f"{msg} (t = {time.time() - t_start:.1f} s)")
    say("coefficients")
    ar, e, reason = decide_arith(tab, dps, arith, exact_seconds)
    try:
        C, facts = algebraic_checks(tab, ar, e, dps)
    except oc.ExactBudgetExceeded:
        budget = ((EXACT_FORCED_SECONDS if arith == "exact" else oc.EXACT_SECONDS)
                  if exact_seconds is None else exact_seconds)
        reason = f"the exact decision ({ar.label}) ran past its {budget:g} s budget"
        say("exact decision over budget: deciding numerically")
        ar, e = _ball(tab, dps, reason)
        C, facts = algebraic_checks(tab, ar, e, dps)
    res = AuditResult(tab.name, tab.s, ar.exact, dps, quick)
    res.facts["arithmetic"] = ar.label
    res.facts["arithmetic_reason"] = reason
    res.facts["decided_to"] = "exactly" if ar.exact else ar.scope
    res.facts["entries"] = tab.precision_text()
    res.facts["digits_given"] = tab.decimal_digits
    res.facts["claimed_order"] = tab.claimed_order
    res.facts["coefficients"] = _coefficient_strings(tab)
    res.checks = C
    res.facts.update(facts)
    hyp22, hyp23 = facts["22"], facts["23"]
    p = facts["predicted_order"]
    if res.get("solvable").status == FAIL:
        # no numerical check can run: (21) has no locally unique solution for this tableau
        for name in ("theorem1", "convergence:skate", "convergence:particle", "constraint", "energy"):
            C.append(Check(name, SKIP, None, "not run: (21) is not solvable for this tableau (see 'solvable')"))
        res.verdict = verdict(res)
        res.seconds = time.time() - t_start
        return res
    say("probe step")
    probe_step(tab)
    say("Theorem 1")
    chk, facts = theorem1_checks(tab, hyp22, hyp23, dps, quick, tuple(theorem_scenes), entry_tolerances(C))
    C.extend(chk)
    res.facts.update(facts)
    say("convergence")
    chk, facts = convergence_checks(tab, p, dps, quick, bool(res.facts.get("order:forced-ode-capped")))
    C.extend(chk)
    res.facts.update(facts)
    say("energy")
    chk, facts = energy_check(tab, quick)
    C.append(chk)
    res.facts.update(facts)
    res.verdict = verdict(res)
    res.seconds = time.time() - t_start
    return res


def verdict(res: AuditResult) -> str:
    f = res.facts
    s = res.s
    parts = []
    sv = res.get("solvable")
    if sv is not None and sv.status == FAIL:
        return (f"{res.tableau} ({s} stage{'s' if s > 1 else ''}): {sv.detail}. Theorem 1 takes the quantities of "
                "(21) as implicit functions of (t0, q0, t1, q1), which do not exist here, and no step can be "
                f"computed, so no numerical check was run. (22) {'holds' if f['22'] else 'does not hold'}; "
                f"the tree conditions give order {f['order:A']} for (A, b) as an RK method. Result: the tableau "
                "cannot be used as a SPARK method; the audit counts that as a failure.")
    c22a, c22b = res.get("22a"), res.get("22b")
    how = ("exactly" if res.exact else f"to {f.get('decided_to') or 'the precision the entries carry'} "
           f"({f.get('arithmetic')})")
    if f["22"]:
        parts.append(f"{res.tableau} ({s} stage{'s' if s > 1 else ''}) satisfies (22a) and (22b) {how}, "
                     "so Theorem 1 applies: the SPARK method is a nonholonomically constrained discrete "
                     "Lagrange-d'Alembert integrator.")
    else:
        bad = [c for c in (c22a, c22b) if c.status == FAIL]
        parts.append(f"{res.tableau} ({s} stage{'s' if s > 1 else ''}) violates "
                     + " and ".join(f"({c.name}) ({c.detail})" for c in bad)
                     + ", so Theorem 1 does not apply.")
    if sv is not None and sv.status == SKIP:
        parts.append(f"Whether (21) is solvable for the method the entries stand for is {sv.detail}.")
    th = [c for c in res.checks if c.name.startswith("theorem1:")]
    summ = res.get("theorem1")
    if summ is not None and summ.status == SKIP:
        parts.append("Theorem 1 was not checked numerically (ldaspark.analysis.discrete missing).")
    elif th:
        decided = [c for c in th if c.status != SKIP]
        nfail = sum(c.status == FAIL for c in decided)
        worst = max([(c.residual or 0.0) for c in decided] or [0.0])
        undecided = [c.name.split(":", 1)[1] for c in th if c.status == SKIP]
        parts.append("The numerical check of Theorem 1 on the paper scenes "
                     + ("agrees" if nfail == 0 and summ.status == PASS
                        else "is not decided at the precision of the entries" if summ.status == INFO
                        else f"fails on {nfail} of {len(decided)} decided scenes" if nfail
                        else "is decided on too few scenes")
                     # no decided scene measured a residual: none to quote (not "0.0e+00")
                     + (f" (largest residual {worst:.1e})" if decided else "")
                     + (f"; not decided on {', '.join(undecided)} (see the checks)" if undecided else "")
                     + ".")
        d = disagreement(res)
        if d:
            parts.append(d)
    if f["23"]:
        parts.append("It satisfies the symmetry conditions (23), so the method is symmetric.")
    elif all(res.get(k) is not None and res.get(k).status == PASS for k in ("23a", "23b", "23c", "23d")):
        parts.append("It satisfies (23a-d), but the rows of omega reversed leave omega's row space (see "
                     "'23-omega'): the adjoint method's (21e) is another equation, so no symmetry is claimed.")
    else:
        parts.append("It does not satisfy (23): no symmetry is claimed.")
    p = f["predicted_order"]
    cap = "+" if f.get("order:forced-ode-capped") else ""
    obs = []
    for sc in ("skate", "particle"):
        r = f.get(f"convergence:{sc}")
        if r:
            why = ("its errors are within the entries' uncertainty" if r.get("entry_floor", 0.0) >= r.get("floor", 0.0) > 0
                   else "its errors are below the working precision's floor")
            obs.append(f"{r['observed']:.2f} on the {sc}" if math.isfinite(r["observed"]) else
                       f"none measurable on the {sc} ({why})")
    conv = [c for c in (res.get(f"convergence:{sc}") for sc in ("skate", "particle")) if c is not None]
    pair_cap = "+" if f.get("order:pair-capped") else ""
    parts.append(f"The tree conditions give order {f['order:pair']}{pair_cap} for the pair (A, A_hat) and {p}{cap} for "
                 f"(A; A_hat, A_tilde) on the forced ODE (6); observed orders {', '.join(obs) or '(none: runs failed)'} "
                 + (("are above it on some scene (reported: the check is one-sided, faster than predicted is "
                     "not a failure)." if any("faster than the trees predict" in c.detail for c in conv)
                     else "agree with it" + (" where measured." if any(c.status == INFO for c in conv) else "."))
                    if all(c.status in (PASS, INFO) for c in conv) and any(c.status == PASS for c in conv)
                    else "do NOT agree with it." if any(c.status == FAIL for c in conv)
                    else "are not measurable at the precision of the entries or of the arithmetic.")
                 + " This prediction ignores the index-2 coupling through psi: Jay proved order 2s for Gauss"
                 " and 2s-2 for Lobatto SPARK methods [26, 27]; for other tableaux, order reduction below the"
                 " tree prediction is possible and only the measurement decides.")
    rs = res.get("row-sums:A")
    if rs is not None and rs.status == INFO:
        parts.append(f"c is not the row sums of A (|c_i - sum_j a_ij| up to {rs.residual:.1e}, beyond the entries' "
                     "uncertainty): a system with t in L or k is evaluated at T_i = t0 + c_i h away from the time "
                     "at which Q_i approximates the solution, so the orders above hold for autonomous systems "
                     "only (the scenes measured here are autonomous).")
    fo = res.get("order:forced-ode")
    if fo is not None and fo.residual and 0 < fo.residual < TINY_DEFECT:
        parts.append(f"The condition that limits the prediction misses by only {fo.residual:.1e}: its "
                     "contribution to the error is of that size, below what the step sizes here can "
                     "measure, so a measured order above the prediction is expected.")
    if p == 0:
        parts.append("Order 0 means the method is not even consistent (e.g. sum b_i != 1"
                     + ("" if res.exact else ", by more than the precision the entries carry")
                     + "): it does not converge, whatever Theorem 1 says about its geometry; the audit counts "
                     "that as a failure.")
    if f.get("claimed_order") is not None:
        parts.append(f"(Claimed order of this built-in: {f['claimed_order']}.)")
    k, en = res.get("constraint"), res.get("energy")
    parts.append(f"The constraint is satisfied to {_fmt(k.residual)} at the step points; the energy error on a "
                 f"short particle run is {_fmt(en.residual if en else None)}.")
    fails = [c.name for c in res.checks if c.status == FAIL]
    parts.append("Result: all checks agree with the theory." if not fails
                 else f"Result: {len(fails)} check(s) failed: {', '.join(fails)}.")
    return " ".join(parts)


#: a first failing order condition smaller than this cannot show in errors measured at h >= 1/64
#: (their error floors are >= 1e-13 in float64): the verdict says so
TINY_DEFECT = 1e-8


def disagreement(res: AuditResult) -> str:
    """A sentence naming a disagreement between the algebraic (22) decision and the numerical
    Theorem 1 check, with its likely cause; "" when they agree (or Theorem 1 was not decided)."""
    summ = res.get("theorem1")
    if summ is None or summ.status == SKIP:
        return ""
    decided = [c for c in res.checks if c.name.startswith("theorem1:") and c.status != SKIP]
    if not decided:
        return ""
    c22 = [c for c in (res.get("22a"), res.get("22b")) if c is not None]
    r22 = max((c.residual or 0.0) for c in c22)
    u22 = max((c.tolerance or 0.0) for c in c22)
    passing = [c for c in decided if c.status == PASS]
    failing = [c for c in decided if c.status == FAIL]
    if not res.facts["22"] and passing:
        tol = min(_tol_of(c) for c in passing)
        cause = (f"the violation of (22) (|residual| {r22:.1e}) is below the resolution of the numerical "
                 f"check (relative tolerance {tol:.0e} at dps {res.dps}), which cannot see it; the algebraic "
                 "decision is the finer one" if r22 < tol else
                 "the violation of (22) is larger than the numerical tolerance, so this is unexpected: "
                 "look at the scenes' BVP classes and residuals")
        return (f"DISAGREEMENT: (22) is violated but the numerical Theorem 1 check passes on "
                f"{', '.join(c.name.split(':', 1)[1] for c in passing)}. Likely cause: {cause}.")
    if res.facts["22"] and failing:
        worst = max((c.residual or 0.0) for c in failing)
        cause = ("the entries carry limited precision: (22) holds only to "
                 f"{r22:.1e} (uncertainty {u22:.1e}), and Theorem 1 is checked with the entries as given"
                 if not res.exact and r22 > 0 else
                 "numerical: the boundary-value problem of (21) or its finite differences at this dps "
                 "(see each scene's BVP class and FD error); (22) itself holds exactly")
        return (f"DISAGREEMENT: (22) holds but the numerical Theorem 1 check fails on "
                f"{', '.join(c.name.split(':', 1)[1] for c in failing)} (largest residual {worst:.1e}). "
                f"Likely cause: {cause}.")
    return ""


def _tol_of(check) -> float:
    """The tolerance of a Theorem 1 scene check."""
    return check.tolerance or 0.0


# --- report ----------------------------------------------------------------------------------
def to_markdown(res: AuditResult, command: str | None = None) -> str:
    L = [f"# ldaspark audit: {res.tableau}", ""]
    L.append(f"- stages s = {res.s}; arithmetic: {res.facts.get('arithmetic')}; working dps {res.dps}; "
             f"{'quick' if res.quick else 'full'} mode; {res.seconds:.1f} s")
    if res.facts.get("arithmetic_reason"):
        L.append(f"- entries: {res.facts.get('entries')}; the algebraic checks are decided "
                 + ("exactly" if res.exact else "in ball arithmetic") + f" because {res.facts['arithmetic_reason']} "
                 "(each check's arithmetic is in the JSON key `arithmetic`)")
    if command:
        L.append(f"- reproduce: `{command}`")
    L.append(f"- exit code {res.exit_code}")
    L += ["", "## Verdict", "", res.verdict, "", "## Checks", "",
          "| check | status | residual | detail |", "|---|---|---|---|"]
    for c in res.checks:
        L.append(f"| {c.name} | {c.status} | {_fmt(c.residual)} | {c.detail.replace('|', chr(92) + '|')} |")
    if res.facts.get("coefficients"):
        L += ["", "## Coefficients", "", "```"]
        L += [f"{k} = {v}" for k, v in res.facts["coefficients"].items()]
        L += ["```"]
    L.append("")
    return "\n".join(L)


# --- CLI -------------------------------------------------------------------------------------
def add_arguments(parser) -> None:
    parser.add_argument("file", nargs="?", default=None, help="tableau JSON file (keys c, A, A_hat, "
                        "A_tilde, b, b_hat, b_tilde, optional omega, name)")
    parser.add_argument("--method", default=None, help="audit a built-in method instead (gauss-S, ...)")
    parser.add_argument("--example", default=None, help="audit a shipped example tableau by name "
                        f"({', '.join(example_names())})")
    parser.add_argument("--dps", type=int, default=30, help="working digits of the numerical checks (default 30)")
    parser.add_argument("--json", default=None, help="write the checks as JSON to this file")
    parser.add_argument("--out", default=None, help="write the markdown report to this file instead of stdout")
    parser.add_argument("--quick", action="store_true", help="fewer step sizes and shorter runs")
    parser.add_argument("--max-stages", type=int, default=None, help="allow tableaux with more than 20 stages")
    parser.add_argument("--arith", choices=("auto", "exact", "mp"), default="auto",
                        help="arithmetic of the algebraic checks (auto: exact when the entries are exact; "
                             "built-ins are exact up to s = 3)")


def safe_load_tableau(path, max_stages=None) -> SparkTableau:
    """The core loader: string entries go through ``numbers.parse_exact_string``, an AST
    whitelist (numbers, + - * / **, sqrt, Rational, pi) that never evaluates Python; the file
    is read only if regular and bounded in size, s <= max_stages (default 20)."""
    return load_tableau(path, max_stages=max_stages)


def example_names() -> list[str]:
    """Names of the example tableaux shipped in ldaspark/data/tableaux (without .json)."""
    from importlib import resources
    d = resources.files("ldaspark") / "data" / "tableaux"
    return sorted(p.name[:-5] for p in d.iterdir() if p.name.endswith(".json")) if d.is_dir() else []


def example_path(name: str):
    """Path of a shipped example tableau."""
    from importlib import resources
    if name not in example_names():
        raise InputError(f"unknown example tableau {name!r}; choose from {', '.join(example_names())}")
    return resources.files("ldaspark") / "data" / "tableaux" / f"{name}.json"


def load_for_args(args) -> SparkTableau:
    example = getattr(args, "example", None)
    if example is not None:
        if args.file is not None or args.method is not None:
            raise InputError("give exactly one of FILE, --method NAME or --example NAME")
        args.file = str(example_path(example))
    if (args.file is None) == (args.method is None):
        raise InputError("give exactly one of FILE or --method NAME (or --example NAME)")
    if args.dps is not None and not (10 <= args.dps <= 200):
        raise InputError(f"--dps must be between 10 and 200, got {args.dps}")
    if args.method is not None:
        ms = getattr(args, "max_stages", None)
        tab = get_method(args.method, max_stages=ms)
        want_exact = args.arith == "exact" or (args.arith == "auto" and tab.s <= 3)
        if want_exact and tab.exact is None:
            tab = get_method(args.method, exact=True, max_stages=ms)
        return tab
    return safe_load_tableau(args.file, getattr(args, "max_stages", None))


def audit_command(args) -> str:
    """The command line that reproduces the audit (the JSON's ``command``, the report's first
    lines): the file shell-quoted (a path with a space was three words) and every option that
    changes what is audited, --max-stages included (without it a 25-stage file is refused)."""
    import shlex
    words = ["ldaspark", "audit"] + (["--method", args.method] if args.method else [str(args.file)])
    words += ["--dps", str(args.dps)] + (["--quick"] if args.quick else [])
    words += ["--arith", args.arith] if args.arith != "auto" else []
    ms = getattr(args, "max_stages", None)
    words += ["--max-stages", str(ms)] if ms is not None else []
    return " ".join(shlex.quote(w) for w in words)


def run(args) -> int:
    from ...core.io import check_destination, check_distinct_outputs
    for path in (args.out, args.json):     # refused now, not after the audit (nor one file of the two)
        check_destination(path)
    # the tableau FILE too: --json FILE replaced the tableau by its audit
    check_distinct_outputs(("the tableau FILE", getattr(args, "file", None)), ("--out", args.out), ("--json", args.json))
    tab = load_for_args(args)
    progress = (lambda msg: print(f"[audit] {msg}", file=sys.stderr, flush=True))
    res = audit(tab, dps=args.dps, quick=args.quick, arith=args.arith, progress=progress)
    cmd = audit_command(args)
    md = to_markdown(res, cmd)
    if args.out:
        from ...core.io import atomic_write_text
        atomic_write_text(args.out, md)
    else:
        print(md)
    if args.json:
        from ...core.io import atomic_write_json
        atomic_write_json(args.json, dict(res.as_dict(), command=cmd))
    return res.exit_code
