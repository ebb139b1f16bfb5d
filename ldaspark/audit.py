"""``ldaspark audit``: a new tableau against the hypotheses of Theorem 1 and the numerics.

    ldaspark audit FILE [--dps D] [--json OUT] [--out MD] [--quick]
    ldaspark audit --method NAME [...]

Checks (each a ``Check``: name, status pass/fail/info/skip, residual, detail):

* shapes, row sums sum_j a_ij = c_i of A, A_hat, A_tilde (information: Theorem 1 does not
  need them, Euler I has A_hat 1 = 1 != c = 0), the rank of omega in (21e);
* (22a), (22b) (hypotheses of Theorem 1) and (23a-d) (symmetry): exact in an algebraic
  number field when the entries are exact, else to the tolerance 10^(3-digits) s;
* tree conditions (order_conditions): A, A_hat, A_tilde as RK methods, the pair (A, A_hat)
  on bi-coloured trees, (A; A_hat, A_tilde) on the forced ODE (6) (the prediction), B/C/D,
  R(inf);
* Theorem 1 on the four paper scenes and the symmetry identities (ldaspark.discrete);
* observed convergence order on the skate (exact solution) and the particle (reference by a
  different, higher-order Gauss SPARK method), the constraint residual, the energy error.

Exit code 0 when (22) holds and every numerical check agrees with the theory, 1 when a check
fails, 2 (LdasparkError) for unusable input.
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field

import mpmath
import numpy as np

from . import order_conditions as oc
from .errors import InputError, LdasparkError, TableauError
from .tableau import SparkTableau, get_method, load_tableau

PASS, FAIL, INFO, SKIP = "pass", "fail", "info", "skip"
PAPER_SCENES = ("particle", "skate", "robot", "mp-particles")
ORDER_SLACK = 0.5   # observed order may fall this far below the prediction before failing


@dataclass
class Check:
    name: str
    status: str
    residual: float | None
    detail: str

    def as_dict(self) -> dict:
        r = self.residual
        if r is not None and not math.isfinite(r):
            r = None  # JSON has no inf/NaN; the detail says what happened
        return {"name": self.name, "status": self.status, "residual": r, "detail": self.detail}


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


# --- helpers -------------------------------------------------------------------------------
def _jsonable(x):
    """Plain JSON: non-finite floats become strings ("nan", "inf"), unknown types str()."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, bool) or x is None or isinstance(x, (int, str)):
        return x
    try:
        f = float(x)
    except (TypeError, ValueError):
        return str(x)
    return f if math.isfinite(f) else str(f)


def _worst(ar, items):
    """items: (value, label). Returns (max |value| as float, its label, all exactly/tol zero)."""
    worst, label, ok, largest = 0.0, None, True, 0.0
    for val, lab in items:
        if not ar.is_zero(val):
            ok = False
            f = abs(ar.to_float(val))
            if label is None or f > worst:
                worst, label = f, lab
        elif not ar.exact:   # within tolerance: still report the size (exact zeros are 0)
            largest = max(largest, abs(float(val)))
    return (worst if not ok else largest), label, ok


def _mode(ar) -> str:
    return "exactly" if ar.exact else f"to tolerance {ar.tol:.1e}"


def _fmt(x) -> str:
    if x is None:
        return "-"
    if isinstance(x, float) and (x == 0 or not math.isfinite(x)):
        return str(x)
    return f"{x:.2e}"


def _coefficient_strings(tab: SparkTableau) -> dict:
    """The entries as printed in the report: exact expressions, else 17 significant digits."""
    if tab.exact is not None and tab.source_digits is None:
        from .tableau import _matrix_to_json
        return {k: _matrix_to_json(M, k, str) for k, M in tab.exact.items()}
    ent = tab.mp_entries(30)
    fmt = lambda v: [fmt(x) for x in v] if isinstance(v, list) else mpmath.nstr(v, 17)
    out = {k: fmt(v) for k, v in ent.items()}
    for k in ("c", "b", "b_hat", "b_tilde"):
        out[k] = [x[0] if isinstance(x, list) else x for x in out[k]]
    return out


# --- algebraic checks ------------------------------------------------------------------------
def check_shapes(tab: SparkTableau) -> Check:
    s = tab.s
    return Check("shapes", PASS, None,
                 f"s = {s}: c, b, b_hat, b_tilde of length {s}; A, A_hat, A_tilde {s}x{s}; omega {s - 1}x{s}")


def check_row_sums(ar, e, name) -> Check:
    """sum_j a_ij = c_i: information only (Theorem 1 needs no such condition; the SPARK
    step evaluates every stage at T_i = t0 + c_i h, so a mismatch lowers the order for
    non-autonomous systems)."""
    s = len(e["c"])
    with ar.context():
        items = [(sum(e[name][i], ar.num(0)) - e["c"][i], f"row {i + 1}") for i in range(s)]
        w, lab, ok = _worst(ar, items)
    if ok:
        return Check(f"row-sums:{name}", PASS, w, f"sum_j {name}_ij = c_i for every i, {_mode(ar)}")
    why = ("A sets the stage points Q_i: a mismatch lowers the stage order" if name == "A" else
           f"every stage is evaluated at T_i = t0 + c_i h, so the row sums of {name} only matter through "
           "the t-dependence of L and k (none in the paper's scenes)")
    return Check(f"row-sums:{name}", INFO, w,
                 f"sum_j {name}_ij != c_i, worst at {lab} (|diff| = {w:.3g}); not a hypothesis of Theorem 1: {why}")


def check_omega(tab: SparkTableau, ar, e, dps) -> Check:
    """rank(omega) = s - 1, so that (21e) with (21f) fixes the s multipliers."""
    s = tab.s
    if s == 1:
        return Check("omega-rank", PASS, None, "s = 1: no (21e) rows")
    with mpmath.workdps(dps):
        om = tab.mp_entries(dps)["omega"]
        sv = mpmath.svd_r(mpmath.matrix(om), compute_uv=False)
        smin = float(min(sv[i] for i in range(s - 1)))
        smax = float(max(sv[i] for i in range(s - 1)))
    tol = 10.0 ** (3 - min(dps, tab.source_digits or dps)) * s
    if smin <= tol * max(smax, 1.0):
        raise TableauError(f"omega is singular (smallest singular value {smin:.2e}): "
                           "(21e) would not determine the multipliers")
    return Check("omega-rank", PASS, smin, f"rank {s - 1} = s-1; singular values in [{smin:.3g}, {smax:.3g}]")


def check_omega_default(tab: SparkTableau, dps) -> Check:
    """Whether the rows of omega span {(b_j c_j^(i-1))_j : i = 1..s-1}, the choice after (21e)
    under which the Gauss and Lobatto convergence results [26, 27] are stated (information)."""
    s = tab.s
    if s == 1:
        return Check("omega-span", INFO, None, "s = 1: no (21e) rows")
    with mpmath.workdps(dps):
        ent = tab.mp_entries(dps)
        b = [x[0] if isinstance(x, list) else x for x in ent["b"]]
        c = [x[0] if isinstance(x, list) else x for x in ent["c"]]
        dflt = [[b[j] * c[j] ** i for j in range(s)] for i in range(s - 1)]
        sv = mpmath.svd_r(mpmath.matrix(ent["omega"] + dflt), compute_uv=False)
        sv = sorted((float(sv[i]) for i in range(min(2 * s - 2, s))), reverse=True)
    tol = 10.0 ** (3 - min(dps, tab.source_digits or dps)) * s * max(sv[0], 1.0)
    rank = sum(x > tol for x in sv)
    if rank == s - 1:
        return Check("omega-span", PASS, sv[s - 1] if len(sv) >= s else 0.0,
                     "rows of omega span {b_j c_j^(i-1)}, i < s (the choice of [26, 27])")
    return Check("omega-span", INFO, sv[s - 1], f"rows of omega do not span {{b_j c_j^(i-1)}} (stacked rank {rank} "
                 f"> s-1 = {s - 1}): convergence results of [26, 27] are stated for that choice")


def check_22a(ar, e) -> Check:
    """(22a) b_hat_i = b_i."""
    with ar.context():
        items = [(e["b_hat"][i] - e["b"][i], f"i = {i + 1}") for i in range(len(e["b"]))]
        w, lab, ok = _worst(ar, items)
    if ok:
        return Check("22a", PASS, w, f"b_hat = b {_mode(ar)}")
    return Check("22a", FAIL, w, f"b_hat_i != b_i, worst at {lab}: |b_hat_i - b_i| = {w:.3g}")


def check_22b(ar, e) -> Check:
    """(22b) b_hat_i a_ij + b_j a_hat_ji - b_hat_i b_j = 0."""
    b, bh, A, Ah = e["b"], e["b_hat"], e["A"], e["A_hat"]
    s = len(b)
    with ar.context():
        items = [(bh[i] * A[i][j] + b[j] * Ah[j][i] - bh[i] * b[j], f"(i, j) = ({i + 1}, {j + 1})")
                 for i in range(s) for j in range(s)]
        w, lab, ok = _worst(ar, items)
    if ok:
        return Check("22b", PASS, w, f"b_hat_i a_ij + b_j a_hat_ji = b_hat_i b_j for all i, j, {_mode(ar)}")
    return Check("22b", FAIL, w, f"violated, worst at {lab}: |b_hat_i a_ij + b_j a_hat_ji - b_hat_i b_j| = {w:.3g}")


def check_23(ar, e) -> list:
    """(23a-d) symmetry conditions; status info when they fail (Theorem 1 does not need them)."""
    s = len(e["c"])
    r = lambda i: s - 1 - i
    out = []
    with ar.context():
        items = [(e["c"][r(i)] + e["c"][i] - ar.num(1), f"i = {i + 1}") for i in range(s)]
        out.append(("23a", items, "c_{s+1-i} + c_i = 1"))
        for tag, M, bv in (("23b", "A", "b"), ("23c", "A_hat", "b_hat"), ("23d", "A_tilde", "b_tilde")):
            items = [(e[M][r(i)][r(j)] + e[M][i][j] - e[bv][j], f"{M} (i, j) = ({i + 1}, {j + 1})")
                     for i in range(s) for j in range(s)]
            items += [(e[bv][r(j)] - e[bv][j], f"{bv} j = {j + 1}") for j in range(s)]
            out.append((tag, items, f"{M}_(s+1-i,s+1-j) + {M}_ij = {bv}_(s+1-j) = {bv}_j"))
        checks = []
        for tag, items, text in out:
            w, lab, ok = _worst(ar, items)
            if ok:
                checks.append(Check(tag, PASS, w, f"{text} {_mode(ar)}"))
            else:
                checks.append(Check(tag, INFO, w, f"fails at {lab} (|residual| = {w:.3g}): the method is not symmetric"))
    return checks


def order_checks(ar, e) -> tuple[list, dict]:
    """Tree orders, simplifying assumptions and R(inf) of A, A_hat, A_tilde, the pair and the
    forced-ODE prediction. Returns (checks, facts)."""
    checks, facts = [], {}
    for M, bv in (("A", "b"), ("A_hat", "b_hat"), ("A_tilde", "b_tilde")):
        r = oc.rk_order(ar, e[M], e[bv])
        sa = oc.simplifying_assumptions(ar, e[M], e[bv], e["c"])
        st = oc.stability(ar, e[M], e[bv])
        facts[f"order:{M}"] = r.order
        facts[f"BCD:{M}"] = sa
        facts[f"R_inf:{M}"] = st.r_inf_str
        more = "" if r.failing is None else f"; first failing tree {r.failing} (residual {r.residual:.3g})"
        checks.append(Check(f"order:{M}", INFO, r.residual,
                            f"({M}, {bv}) has order {r.order}{'+' if r.complete else ''} as an RK method "
                            f"(rooted trees to order {r.max_order}){more}"))
        checks.append(Check(f"simplifying:{M}", INFO, None,
                            f"B({sa['B']}), C({sa['C']}), D({sa['D']}) with nodes c"))
        checks.append(Check(f"stability:{M}", INFO, None,
                            f"R(inf) = {st.r_inf_str}" + (f" ({st.note})" if st.A_singular else
                                                          " (A invertible: 1 - b^T A^-1 1)")
                            + ("; L-stable-type damping" if st.r_inf == 0 else "")))
    pr = oc.pair_order(ar, e["A"], e["b"], e["A_hat"], e["b_hat"])
    facts["order:pair"] = pr.order
    more = "" if pr.failing is None else f"; first failing tree {pr.failing} (residual {pr.residual:.3g})"
    checks.append(Check("order:pair(A,A_hat)", INFO, pr.residual,
                        f"partitioned pair (A, b) for q' = v, (A_hat, b_hat) for p' = F: order "
                        f"{pr.order}{'+' if pr.complete else ''} (bi-coloured trees to order {pr.max_order}){more}"))
    so = oc.spark_ode_order(ar, e)
    facts["order:forced-ode"] = so.order
    facts["order:forced-ode-capped"] = so.complete
    more = "" if so.failing is None else f"; first failing tree {so.failing} (residual {so.residual:.3g})"
    checks.append(Check("order:forced-ode", INFO, so.residual,
                        f"(A; A_hat, A_tilde) on q' = v, p' = F + R with psi a given smooth forcing: order "
                        f"{so.order}{'+' if so.complete else ''} (coloured trees to order {so.max_order}){more}"))
    return checks, facts


# --- numerical checks ------------------------------------------------------------------------
def probe_step(tab: SparkTableau) -> None:
    """One float64 step on the skate and the particle; unusable tableau -> InputError."""
    from .scenes import get_scene
    from .spark import SparkMethod
    for name in ("skate", "particle"):
        sc = get_scene(name)
        t0, q0, v0 = sc.initial()
        try:
            r = SparkMethod(sc.system, tab).step(t0, np.array(q0), np.array(v0), 0.05)
        except LdasparkError as exc:
            raise InputError(f"the SPARK step (21) cannot be solved for tableau {tab.name} "
                             f"({name}, h = 0.05): {str(exc).splitlines()[0]}") from None
        if not (np.all(np.isfinite(r.q1)) and np.all(np.isfinite(r.v1))):
            raise InputError(f"the SPARK step (21) gives non-finite values for tableau {tab.name}")


def _run(tab, scene, N, t_end, dps):
    from .spark import integrate
    t0, q0, v0 = scene.initial(dps)
    with mpmath.workdps(dps or 15):
        h = mpmath.mpf(t_end) / N if dps else t_end / N
        return integrate(scene.system, tab, t0, q0, v0, h, n_steps=N, dps=dps)


def _err(sol, qref, vref) -> float:
    dq = max(abs(float(x - y)) for x, y in zip(sol.q[-1], qref))
    dv = max(abs(float(x - y)) for x, y in zip(sol.v[-1], vref))
    return max(dq, dv)


def _reference_tableau(tab):
    """A Gauss SPARK method of higher order than anything we audit and not the tableau itself."""
    from .tableau import gauss
    s = 6 if tab.s == 5 else 5   # never the audited tableau itself, even a gauss-5 copy from a file
    return gauss(s)


def observed_order(tab, scene_name, Ns, t_end, dps, floor):
    """Errors at t_end for N in Ns and the slope of the finest pair above the error floor."""
    from .scenes import get_scene
    sc = get_scene(scene_name)
    if sc.exact is not None:
        qref, vref, _ = sc.exact_solution(t_end, dps)
        ref_name = "exact solution"
    else:
        ref = _reference_tableau(tab)
        Nref = 2 * max(Ns)
        sol = _run(ref, sc, Nref, t_end, dps)
        qref, vref = sol.q[-1], sol.v[-1]
        ref_name = f"{ref.name} with h = {t_end}/{Nref}"
    errs, kmax = [], 0.0
    for N in Ns:
        sol = _run(tab, sc, N, t_end, dps)
        errs.append(_err(sol, qref, vref))
        kmax = max(kmax, max(abs(float(x)) for x in sol.constraint.reshape(-1)))
    slopes = [math.log(errs[i] / errs[i + 1]) / math.log(Ns[i + 1] / Ns[i])
              if errs[i + 1] > 0 and errs[i] > 0 else float("nan") for i in range(len(Ns) - 1)]
    usable = [sl for sl, e in zip(slopes, errs[1:]) if e > floor and math.isfinite(sl)]
    obs = usable[-1] if usable else float("nan")
    return {"scene": scene_name, "N": list(Ns), "t_end": t_end, "errors": errs, "slopes": slopes,
            "observed": obs, "reference": ref_name, "max_constraint": kmax}


def _step_counts(p: int, quick: bool):
    if p <= 1:
        Ns = [16, 32, 64]
    elif p <= 2:
        Ns = [8, 16, 32]
    elif p <= 4:
        Ns = [4, 8, 16]
    else:
        Ns = [4, 8, 16]
    return Ns[:2] if quick and p >= 3 else Ns


def convergence_checks(tab, predicted, dps, quick, capped=False):
    """Observed order on the skate (exact solution) and the particle (reference solution)."""
    checks, facts = [], {}
    # float64 suffices while the finest error stays far above round-off (order <= 4 at the
    # step counts below); higher orders run at dps digits
    wdps = None if predicted <= 4 else dps
    digits = 15 if wdps is None else min(dps, tab.source_digits or dps)
    floor = 10.0 ** (4 - digits)
    facts["convergence_dps"] = wdps
    kmax = 0.0
    for scene_name, t_end in (("skate", 1), ("particle", 1)):
        Ns = _step_counts(predicted, quick)
        try:
            res = observed_order(tab, scene_name, Ns, t_end, wdps, floor)
        except LdasparkError as exc:   # e.g. Newton fails at the larger steps
            checks.append(Check(f"convergence:{scene_name}", FAIL, None,
                                f"integration failed: {str(exc).splitlines()[0]}"))
            continue
        kmax = max(kmax, res["max_constraint"])
        facts[f"convergence:{scene_name}"] = res
        obs = res["observed"]
        errs = ", ".join(f"h=1/{N}: {e:.2e}" for N, e in zip(res["N"], res["errors"]))
        if not math.isfinite(obs):
            status, what = FAIL, "no usable slope (errors at the floor or zero)"
        elif obs < predicted - ORDER_SLACK:
            status, what = FAIL, f"observed {obs:.2f} below the predicted {predicted}"
        elif capped and obs > predicted + 1 - ORDER_SLACK:
            status, what = PASS, f"observed {obs:.2f}, consistent with the prediction >= {predicted} (tree cap)"
        elif obs > predicted + 1 - ORDER_SLACK:
            status, what = PASS, f"observed {obs:.2f} above the predicted {predicted} (superconvergence on this scene)"
        else:
            status, what = PASS, f"observed {obs:.2f} vs predicted {predicted}"
        checks.append(Check(f"convergence:{scene_name}", status, abs(obs - predicted) if math.isfinite(obs) else None,
                            f"{what}; errors in (q, v) at t = {t_end} vs {res['reference']} "
                            f"({'float64' if wdps is None else f'dps {wdps}'}): {errs}"))
    ktol = 1e3 * (2.0 ** -52 if wdps is None else 10.0 ** (-wdps))
    checks.append(Check("constraint", PASS if kmax <= ktol else FAIL, kmax,
                        f"max |k(t_n, q_n, v_n)| over the convergence runs = {kmax:.2e} "
                        f"(tolerance {ktol:.0e}: (21f) imposes k = 0 at every step point)"))
    facts["max_constraint"] = kmax
    return checks, facts


def energy_check(tab, quick):
    """Energy error of the particle scene (E conserved, 8.1) on a short float64 run at h and
    h/2; information (the theorem says nothing quantitative about energy)."""
    from .scenes import get_scene
    sc = get_scene("particle")
    T = 5.0 if quick else 10.0
    out = []
    for N in (50, 100) if quick else (100, 200):
        try:
            sol = _run(tab, sc, N, T, None)
        except LdasparkError as exc:
            return Check("energy", FAIL, None, f"particle run with h = {T / N:g} failed: "
                                               f"{str(exc).splitlines()[0]}"), {}
        E = np.asarray(sol.energy, dtype=float)
        out.append((T / N, float(np.max(np.abs(E - E[0])))))
    (h1, e1), (h2, e2) = out
    rate = math.log(e1 / e2) / math.log(2) if e1 > 0 and e2 > 0 else float("nan")
    return Check("energy", INFO, e2,
                 f"particle, t in [0, {T:g}]: max |E - E0| = {e1:.2e} (h = {h1:g}), {e2:.2e} (h = {h2:g}); "
                 f"rate {rate:.2f}"), {"energy": out, "energy_rate": rate}


# --- Theorem 1 -------------------------------------------------------------------------------
def theorem1_checks(tab, hyp22, hyp23, dps, quick, scenes=PAPER_SCENES):
    """Theorem 1 and the symmetry identities on the four paper scenes, via ldaspark.discrete
    (issue 3). Returns (checks, facts)."""
    import importlib.util
    if importlib.util.find_spec("ldaspark.discrete") is None:
        return [Check("theorem1", SKIP, None, "ldaspark.discrete (issue 3) is not available: "
                                              "Theorem 1 not checked numerically")], {}
    return _theorem1_with_discrete(tab, hyp22, hyp23, dps, quick, scenes)


TEETH = 1e-6        # a Theorem 1 tolerance above this could not tell (22) from its violation
THEOREM_H = "1/10"   # step of the base point (t0, q0) -> (t1, q1) for Theorem 1 and symmetry


def _theorem1_tol(tab, dps, fd_error):
    """Relative tolerance of the Theorem 1 identities: above the finite-difference error
    estimate, the working precision and the precision of the coefficients."""
    src = tab.source_digits
    return max(10 * fd_error, 10.0 ** (-dps / 2), 10.0 ** (3 - src) if src else 0.0)


def _theorem1_with_discrete(tab, hyp22, hyp23, dps, quick, scenes):
    from . import discrete
    from .scenes import get_scene
    checks, facts = [], {}
    d = dps
    for name in scenes:
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
            if _theorem1_tol(tab, dd, r["fd_error"]) <= TEETH:
                break
        if r is None:
            checks.append(Check(f"theorem1:{name}", SKIP, None,
                                f"not decided: boundary-value solve of (21) failed ({err}) at dps "
                                f"{d}{'' if quick else f' and {d + 20}'}; the implicit functions of Theorem 1 "
                                "are not established numerically here"))
            continue
        wp = r["wellposed"]
        if not quick:
            try:
                wpc = discrete.classify_wellposedness(sc.system, tab, t0, q0, v0, THEOREM_H, dps=(d, d + 20))
                wp = f"{wpc['class']} (rank deficiency {wpc['rank_deficiency']}, decided at dps {d}, {d + 20} and h, h/2)"
            except LdasparkError as exc:
                wp = f"{wp} (classification failed: {exc})"
        else:
            wp = f"{wp} (rank deficiency {r['rank_deficiency']} at dps {r['dps_fd']})"
        res = max(r["theorem1-q0"], r["theorem1-q1"])
        tol = _theorem1_tol(tab, r["dps"], r["fd_error"])
        facts[f"theorem1:{name}"] = {k: v for k, v in r.items() if k != "null_support"}
        ok = res <= tol
        claim = ("agrees with Theorem 1" if hyp22 else
                 "holds although (22) fails" if ok else "fails, as expected without (22)")
        status = PASS if ok else FAIL
        if tol > TEETH:
            status, claim = SKIP, f"not decided (tolerance {tol:.0e} above {TEETH:.0e} at dps {r['dps']})"
        checks.append(Check(
            f"theorem1:{name}", status, res,
            f"{claim}: |dL_d/dq0 + p0 + f_d^-|, |dL_d/dq1 - p1 + f_d^+| relative = "
            f"{r['theorem1-q0']:.1e}, {r['theorem1-q1']:.1e} (tolerance {tol:.0e}; FD error {r['fd_error']:.0e}; "
            f"without the forces {r['without_forces_q0']:.1e}); h = {THEOREM_H}, dps {r['dps']}; BVP {wp}"))
    th = [c for c in checks if c.name.startswith("theorem1:")]
    decided = [c for c in th if c.status != SKIP]
    nfail = sum(c.status == FAIL for c in decided)
    need = min(2, len(th))
    if len(decided) < need:
        checks.append(Check("theorem1", FAIL, None, f"decided on only {len(decided)} of {len(th)} scenes "
                                                    f"(at least {need} needed)"))
    else:
        checks.append(Check("theorem1", FAIL if nfail else PASS,
                            max((c.residual or 0.0) for c in decided),
                            f"decided on {len(decided)} of {len(th)} scenes, {nfail} failing"))
    if hyp23:
        for name in [x for x in scenes if x in ("skate", "particle")] if quick else scenes:
            sc = get_scene(name)
            t0, q0, v0 = sc.initial(d + 5)
            try:
                r = discrete.check_symmetry(sc.system, tab, t0, q0, v0, THEOREM_H, dps=d)
            except LdasparkError as exc:
                checks.append(Check(f"symmetry:{name}", SKIP, None,
                                    f"not decided: forward/reverse BVP solve failed ({str(exc).splitlines()[0]})"))
                continue
            keys = ("symmetry-Ld", "symmetry-fd-plus", "symmetry-fd-minus", "symmetry-Phi")
            # With a singular (non-gauge) BVP Jacobian the implicit functions of Theorem 1 are
            # not unique, so f_d^+- (built from dV/dq) depend on the gauge fixing: only L_d and
            # the map Phi_h are then decidable; the f_d parts are reported, not judged.
            judged = keys if r["wellposed"] != "singular" else ("symmetry-Ld", "symmetry-Phi")
            res = max(r[k] for k in judged)
            tol = _theorem1_tol(tab, d, 0.0)
            facts[f"symmetry:{name}"] = {k: v for k, v in r.items() if isinstance(v, (int, float, str))}
            note = "" if judged == keys else "; f_d parts not judged: BVP singular, f_d not unique"
            checks.append(Check(
                f"symmetry:{name}", PASS if res <= tol else FAIL, res,
                "L_d(t1,q1,t0,q0) + L_d, f_d^+(rev) + f_d^-, f_d^-(rev) + f_d^+, Phi_-h(Phi_h(y)) - y: "
                + ", ".join(f"{r[k]:.1e}" for k in keys) + f" (tolerance {tol:.0e}; BVP {r['wellposed']}{note})"))
        sy = [c for c in checks if c.name.startswith("symmetry:")]
        dec = [c for c in sy if c.status != SKIP]
        if sy:
            nf = sum(c.status == FAIL for c in dec)
            checks.append(Check("symmetry", FAIL if (nf or not dec) else PASS,
                                max([(c.residual or 0.0) for c in dec] or [0.0]),
                                f"decided on {len(dec)} of {len(sy)} scenes, {nf} failing"
                                + ("" if dec else " (at least one needed)")))
    else:
        checks.append(Check("symmetry", SKIP, None, "(23) does not hold: Theorem 1 claims no symmetry"))
    return checks, facts


# --- the audit -------------------------------------------------------------------------------
def predicted_order(tab, facts) -> int:
    """The order the conditions predict: the forced-ODE order (3-coloured trees)."""
    return int(facts["order:forced-ode"])


def audit(tab: SparkTableau, dps: int = 30, quick: bool = False, arith: str = "auto",
          progress=None, theorem_scenes=PAPER_SCENES) -> AuditResult:
    """Run every check on ``tab``; see the module docstring. ``theorem_scenes`` restricts the
    Theorem 1 scenes (the CLI always uses the four paper scenes; tests use fewer)."""
    t_start = time.time()
    _say = progress or (lambda msg: None)
    say = lambda msg: _say(f"{msg} (t = {time.time() - t_start:.1f} s)")
    if arith == "exact" or (arith == "auto" and tab.is_exact):
        if not tab.is_exact:
            raise InputError(f"tableau {tab.name} has inexact entries: --arith exact is not possible")
        ar, e = oc.exact_arith(tab)
    else:
        ar, e = oc.mp_arith(tab, dps)
    res = AuditResult(tab.name, tab.s, ar.exact, dps, quick)
    res.facts["arithmetic"] = (f"exact in {ar.K}" if ar.exact
                               else f"mpmath dps {dps}, tolerance {ar.tol:.1e}")
    res.facts["claimed_order"] = tab.claimed_order
    res.facts["coefficients"] = _coefficient_strings(tab)
    C = res.checks
    say("coefficients")
    C.append(check_shapes(tab))
    for M in ("A", "A_hat", "A_tilde"):
        C.append(check_row_sums(ar, e, M))
    C.append(check_omega(tab, ar, e, dps))
    C.append(check_omega_default(tab, dps))
    C.append(check_22a(ar, e))
    C.append(check_22b(ar, e))
    C.extend(check_23(ar, e))
    hyp22 = C[-6].status == PASS and C[-5].status == PASS
    hyp23 = all(c.status == PASS for c in C[-4:])
    res.facts["22"] = hyp22
    res.facts["23"] = hyp23
    say("order conditions")
    chk, facts = order_checks(ar, e)
    C.extend(chk)
    res.facts.update(facts)
    p = predicted_order(tab, res.facts)
    res.facts["predicted_order"] = p
    C.append(Check("consistent", PASS if p >= 1 else FAIL, None,
                   f"the conditions predict order {p}" + (" >= 1: the method converges" if p >= 1 else
                                                          ": sum b != 1 or similar, the method cannot converge")))
    say("probe step")
    probe_step(tab)
    say("Theorem 1")
    chk, facts = theorem1_checks(tab, hyp22, hyp23, dps, quick, tuple(theorem_scenes))
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
    c22a, c22b = res.get("22a"), res.get("22b")
    how = ("exactly" if res.exact else f"to the tolerance of its precision ({res.facts.get('arithmetic')})")
    if f["22"]:
        parts.append(f"{res.tableau} ({s} stage{'s' if s > 1 else ''}) satisfies (22a) and (22b) {how}, "
                     "so Theorem 1 applies: the SPARK method is a nonholonomically constrained discrete "
                     "Lagrange-d'Alembert integrator.")
    else:
        bad = [c for c in (c22a, c22b) if c.status == FAIL]
        parts.append(f"{res.tableau} ({s} stage{'s' if s > 1 else ''}) violates "
                     + " and ".join(f"({c.name}) ({c.detail})" for c in bad)
                     + ", so Theorem 1 does not apply.")
    th = [c for c in res.checks if c.name.startswith("theorem1:")]
    summ = res.get("theorem1")
    if summ is not None and summ.status == SKIP:
        parts.append("Theorem 1 was not checked numerically (ldaspark.discrete missing).")
    elif th:
        decided = [c for c in th if c.status != SKIP]
        nfail = sum(c.status == FAIL for c in decided)
        worst = max([(c.residual or 0.0) for c in decided] or [0.0])
        undecided = [c.name.split(":", 1)[1] for c in th if c.status == SKIP]
        parts.append(f"The numerical check of Theorem 1 on the paper scenes "
                     + ("agrees" if nfail == 0 and summ.status == PASS
                        else f"fails on {nfail} of {len(decided)} decided scenes" if nfail
                        else "is decided on too few scenes")
                     + f" (largest residual {worst:.1e})"
                     + (f"; not decided on {', '.join(undecided)} (see the checks)" if undecided else "")
                     + ".")
    if f["23"]:
        parts.append("It satisfies the symmetry conditions (23), so the method is symmetric.")
    else:
        parts.append("It does not satisfy (23): no symmetry is claimed.")
    p = f["predicted_order"]
    cap = "+" if f.get("order:forced-ode-capped") else ""
    obs = []
    for sc in ("skate", "particle"):
        r = f.get(f"convergence:{sc}")
        if r:
            obs.append(f"{r['observed']:.2f} on the {sc}")
    parts.append(f"The tree conditions give order {f['order:pair']} for the pair (A, A_hat) and {p}{cap} for "
                 f"(A; A_hat, A_tilde) on the forced ODE (6); observed orders {', '.join(obs) or '(none: runs failed)'} "
                 + ("agree with it." if all(res.get(f'convergence:{sc}').status == PASS for sc in ("skate", "particle"))
                    else "do NOT agree with it.")
                 + " This prediction ignores the index-2 coupling through psi: Jay proved order 2s for Gauss"
                 " and 2s-2 for Lobatto SPARK methods [26, 27]; for other tableaux, order reduction below the"
                 " tree prediction is possible and only the measurement decides.")
    if p == 0:
        parts.append("Order 0 means the method is not even consistent (e.g. sum b_i != 1): it does not "
                     "converge, whatever Theorem 1 says about its geometry; the audit counts that as a failure.")
    if f.get("claimed_order") is not None:
        parts.append(f"(Claimed order of this built-in: {f['claimed_order']}.)")
    k, en = res.get("constraint"), res.get("energy")
    parts.append(f"The constraint is satisfied to {_fmt(k.residual)} at the step points; the energy error on a "
                 f"short particle run is {_fmt(en.residual if en else None)}.")
    fails = [c.name for c in res.checks if c.status == FAIL]
    parts.append("Result: all checks agree with the theory." if not fails
                 else f"Result: {len(fails)} check(s) failed: {', '.join(fails)}.")
    return " ".join(parts)


# --- report ----------------------------------------------------------------------------------
def to_markdown(res: AuditResult, command: str | None = None) -> str:
    L = [f"# ldaspark audit: {res.tableau}", ""]
    L.append(f"- stages s = {res.s}; arithmetic: {res.facts.get('arithmetic')}; working dps {res.dps}; "
             f"{'quick' if res.quick else 'full'} mode; {res.seconds:.1f} s")
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
    parser.add_argument("--dps", type=int, default=30, help="working digits of the numerical checks (default 30)")
    parser.add_argument("--json", default=None, help="write the checks as JSON to this file")
    parser.add_argument("--out", default=None, help="write the markdown report to this file instead of stdout")
    parser.add_argument("--quick", action="store_true", help="fewer step sizes and shorter runs")
    parser.add_argument("--arith", choices=("auto", "exact", "mp"), default="auto",
                        help="arithmetic of the algebraic checks (auto: exact when the entries are exact; "
                             "built-ins are exact up to s = 3)")


def safe_load_tableau(path) -> SparkTableau:
    """The core loader: string entries go through ``tableau.parse_exact_string``, an AST
    whitelist (numbers, + - * / **, sqrt, Rational, pi) that never evaluates Python."""
    return load_tableau(path)


def load_for_args(args) -> SparkTableau:
    if (args.file is None) == (args.method is None):
        raise InputError("give exactly one of FILE or --method NAME")
    if args.dps is not None and not (10 <= args.dps <= 200):
        raise InputError(f"--dps must be between 10 and 200, got {args.dps}")
    if args.method is not None:
        tab = get_method(args.method)
        want_exact = args.arith == "exact" or (args.arith == "auto" and tab.s <= 3)
        if want_exact and tab.exact is None:
            tab = get_method(args.method, exact=True)
        return tab
    return safe_load_tableau(args.file)


def run(args) -> int:
    tab = load_for_args(args)
    progress = (lambda msg: print(f"[audit] {msg}", file=sys.stderr, flush=True))
    res = audit(tab, dps=args.dps, quick=args.quick, arith=args.arith, progress=progress)
    cmd = "ldaspark audit " + (f"--method {args.method}" if args.method else str(args.file)) \
        + f" --dps {args.dps}" + (" --quick" if args.quick else "") \
        + (f" --arith {args.arith}" if args.arith != "auto" else "")
    md = to_markdown(res, cmd)
    if args.out:
        from .io import atomic_write_text
        atomic_write_text(args.out, md)
    else:
        print(md)
    if args.json:
        from .io import atomic_write_json
        atomic_write_json(args.json, dict(res.as_dict(), command=cmd))
    return res.exit_code
