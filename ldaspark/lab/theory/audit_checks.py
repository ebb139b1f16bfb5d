"""The individual checks of ``ldaspark audit`` (``ldaspark.lab.theory.audit``): algebraic ones on the
coefficients ((22a), (22b), (23a-d), row sums, omega of (21e), order conditions by trees, B/C/D,
R(inf)) and numerical ones (a probe step, observed orders on the skate and the particle, the
energy). Each returns a ``Check``."""
from __future__ import annotations

import math
from dataclasses import dataclass

import mpmath
import numpy as np

from ...analysis import order_conditions as oc
from ...core.errors import InputError, LdasparkError, TableauError
from ...core.tableau import SparkTableau

PASS, FAIL, INFO, SKIP = "pass", "fail", "info", "skip"
# observed - predicted allowed below the prediction (one-sided: above it is reported, not failed).
# Below 1/2, so that a prediction one too high fails where the right one passes (obs - (p + 1) <=
# -(1 - slack) < -slack).
# Measured on every built-in up to s = 4, skate and particle, finest pair: worst gap 0.31
# (Gauss-4 on the particle in --quick, 8.31; 0.06 in the full run).
ORDER_SLACK = 0.45


@dataclass
class Check:
    name: str
    status: str
    residual: float | None
    detail: str
    #: the arithmetic that decided an algebraic check ("exact in QQ<sqrt(3)>", "arb balls at 80
    #: digits, entries: ..."); None for the numerical checks
    arithmetic: str | None = None
    #: the uncertainty the residual was compared with (0 for an exact decision; None when n/a)
    tolerance: float | None = None

    def as_dict(self) -> dict:
        r = self.residual
        if r is not None and not math.isfinite(r):
            r = None  # JSON has no inf/NaN; the detail says what happened
        tol = self.tolerance if self.tolerance is None or math.isfinite(self.tolerance) else None
        return {"name": self.name, "status": self.status, "residual": r, "detail": self.detail,
                "arithmetic": self.arithmetic, "tolerance": tol}


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
    """items: (value, label). Returns (max |value| as float, its label, all zero, uncertainty):
    all zero exactly, or to the precision of the arithmetic (a ball containing 0, |x| <= tol);
    the residual is the largest nonzero one when some is nonzero, else the largest within the
    uncertainty (exact zeros are 0); the uncertainty is the largest radius when all hold (0 when
    exact), else the radius of the worst violated one (the one the message compares with it)."""
    worst, label, ok, largest, rad, worst_rad = 0.0, None, True, 0.0, 0.0, 0.0
    for val, lab in items:
        r = ar.radius(val)
        rad = max(rad, r)
        if not ar.is_zero(val):
            ok = False
            f = abs(ar.to_float(val))
            if label is None or f > worst:
                worst, label, worst_rad = f, lab, r
        elif not ar.exact:   # within the uncertainty: still report the size (exact zeros are 0)
            largest = max(largest, abs(ar.to_float(val)))
    return (worst if not ok else largest), label, ok, (rad if ok else worst_rad)


def _mode(ar, w: float = 0.0, rad: float = 0.0) -> str:
    """How a condition that holds was decided, for the check's detail."""
    if ar.exact:
        return "exactly"
    if ar.ball:
        held = f"holds to {digits_of(rad)} digits: " if rad > 0 else ""
        return (f"to {ar.scope or f'{ar.dps} digits'} ({held}largest |residual| {w:.1e}, within the "
                f"uncertainty {rad:.1e})")
    return f"to tolerance {ar.tol:.1e}"


def _beyond(ar, rad: float) -> str:
    """Why a nonzero residual is a violation, for the check's detail."""
    if ar.exact:
        return "exactly nonzero"
    if ar.ball:
        return f"beyond the uncertainty {rad:.1e} ({ar.scope or f'{ar.dps} digits'})"
    return f"above the tolerance {ar.tol:.1e}"


def _tol(ar, rad: float) -> float:
    return 0.0 if ar.exact else rad if ar.ball else float(ar.tol)


def _fmt(x) -> str:
    if x is None:
        return "-"
    if isinstance(x, float) and (x == 0 or not math.isfinite(x)):
        return str(x)
    return f"{x:.2e}"


def _coefficient_strings(tab: SparkTableau) -> dict:
    """The entries as printed in the report: as the file gave them when read from a file, else
    exact expressions, else 17 significant digits."""
    if tab.sources is not None:
        show = lambda x: f"{show(x[0])} + ({x[1]})" if isinstance(x, tuple) else str(x)
        out = {k: [[show(x) for x in r] if isinstance(r, list) else show(r) for r in v] for k, v in tab.sources.items()}
        if "omega" not in out and tab.exact is not None:
            from ...core.tableau import _matrix_to_json
            out["omega"] = _matrix_to_json(tab.exact["omega"], "omega", str)
        return out
    if tab.exact is not None and tab.source_digits is None:
        from ...core.tableau import _matrix_to_json
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
        w, lab, ok, rad = _worst(ar, items)
    if ok:
        return Check(f"row-sums:{name}", PASS, w, f"sum_j {name}_ij = c_i for every i, {_mode(ar, w, rad)}",
                     ar.label, _tol(ar, rad))
    why = ("A sets the stage points Q_i: a mismatch lowers the stage order" if name == "A" else
           f"every stage is evaluated at T_i = t0 + c_i h, so the row sums of {name} only matter through "
           "the t-dependence of L and k (none in the paper's scenes)")
    return Check(f"row-sums:{name}", INFO, w,
                 f"sum_j {name}_ij != c_i, worst at {lab} (|diff| = {w:.3g}, {_beyond(ar, rad)}); "
                 f"not a hypothesis of Theorem 1: {why}", ar.label, _tol(ar, rad))


def check_omega(tab: SparkTableau, ar, e, dps) -> Check:
    """rank(omega) = s - 1, so that (21e) with (21f) fixes the s multipliers: decided at the
    precision the entries carry (``tableau.omega_rank``: singular values at enough digits against
    the uncertainty of omega, correct for Vandermonde-type rows)."""
    from ...core.tableau import omega_rank
    s = tab.s
    if s == 1:
        return Check("omega-rank", PASS, None, "s = 1: no (21e) rows")
    r = omega_rank(tab)
    sig = r["sigma"]
    smin, smax = sig[s - 2], sig[0]
    how = (f"mpmath singular values at dps {r['dps']} against the uncertainty {r['radius']:.1e} of omega "
           "(Frobenius norm of its entries' radii) and of the arithmetic")
    if r["rank"] < s - 1:
        raise TableauError(f"omega is singular (smallest singular value {smin:.2e}, within {r['bound']:.1e}): "
                           "(21e) would not determine the multipliers")
    return Check("omega-rank", PASS, smin, f"rank {s - 1} = s-1; singular values in [{smin:.3g}, {smax:.3g}], "
                 f"the smallest above the uncertainty {r['bound']:.1e}", how, r["bound"])


def check_omega_default(tab: SparkTableau, dps) -> Check:
    """Whether the rows of omega span {(b_j c_j^(i-1))_j : i = 1..s-1}, the choice after (21e)
    under which the Gauss and Lobatto convergence results [26, 27] are stated (information):
    the rank of omega stacked on those rows (``omega_rank``), s-1 when they span the same space."""
    from ...core.tableau import default_rows_radius, omega_rank
    s = tab.s
    if s == 1:
        return Check("omega-span", INFO, None, "s = 1: no (21e) rows")
    w = omega_rank(tab)["dps"]
    with mpmath.workdps(w):
        ent = tab.mp_entries(w)
        b = [x[0] if isinstance(x, list) else x for x in ent["b"]]
        c = [x[0] if isinstance(x, list) else x for x in ent["c"]]
        dflt = [[b[j] * c[j] ** i for j in range(s)] for i in range(s - 1)]
    r = omega_rank(tab, w, dflt)
    sv, rank = r["sigma"], r["rank"]
    # the stacked rows carry the uncertainty of omega (in the bound) and that of the default rows,
    # from b and c: twice omega's was 2e-58 for an exact omega beside 10-digit b, c (Weyl: the
    # sum of the two Frobenius radii bounds the stacked one)
    tol = r["bound"] + default_rows_radius(tab) + (r["bound"] - r["radius"])
    rank = sum(x > tol for x in sv)
    how = f"mpmath singular values at dps {w}"
    if rank == s - 1:
        return Check("omega-span", PASS, sv[s - 1] if len(sv) >= s else 0.0,
                     "rows of omega span {b_j c_j^(i-1)}, i < s (the choice of [26, 27])", how, tol)
    return Check("omega-span", INFO, sv[s - 1], f"rows of omega do not span {{b_j c_j^(i-1)}} (stacked rank {rank} "
                 f"> s-1 = {s - 1}): convergence results of [26, 27] are stated for that choice", how, tol)


def check_23_omega(tab: SparkTableau) -> Check:
    """The hypothesis on omega that (23a-d) leave implicit: the adjoint method (reversed stages)
    imposes sum_j omega_(i,s+1-j) K_j = 0 in (21e), the same equations exactly when the reversed
    rows span omega's rows. [26, 27]'s omega_ij = b_j c_j^(i-1) does under (23a) and b_(s+1-j) = b_j
    (b_j (1 - c_j)^(i-1) is a combination of its rows); Gauss-3 with the rows of the identity is not
    symmetric (the identities miss by 1.7e-7 on the particle). The rank of omega stacked on its
    reversal (``omega_rank``), s-1 when the rows span the same space; the reversed rows carry
    omega's uncertainty, so twice omega's bound."""
    from ...core.tableau import omega_rank
    s = tab.s
    if s <= 1:
        return Check("23-omega", PASS, None, "s = 1: omega has no rows")
    w = omega_rank(tab)["dps"]
    with mpmath.workdps(w):
        rev = [list(reversed(r)) for r in tab.mp_entries(w)["omega"]]
    r = omega_rank(tab, w, rev)
    sv, tol = r["sigma"], 2 * r["bound"]
    rank = sum(x > tol for x in sv)
    how = f"mpmath singular values at dps {w}"
    if rank == s - 1:
        return Check("23-omega", PASS, sv[s - 1] if len(sv) >= s else 0.0,
                     "the rows of omega reversed, omega_(i,s+1-j), span omega's rows: the adjoint method "
                     "imposes the same (21e)", how, tol)
    return Check("23-omega", INFO, sv[s - 1], f"the rows of omega reversed, omega_(i,s+1-j), leave omega's row "
                 f"space (stacked rank {rank} > s-1 = {s - 1}): the adjoint method's (21e) is another equation, "
                 "so (23) does not make the method symmetric", how, tol)


def check_solvable(tab: SparkTableau) -> Check:
    """Whether (21) determines its unknowns for small h: eliminating V_i - v_0 (from (21b), M
    invertible) and v_1 - v_0 (from (21d)), (21e) and (21f) at h -> 0 read
    ([omega A_tilde; b_tilde^T] (x) K M^-1 K^T) Psi = 0, so the Newton matrix of (21) is
    nonsingular for small h (a regular mass matrix M and constraint Jacobian K) exactly when the
    s x s matrix N = [omega A_tilde; b_tilde^T] is. Its rank is decided as omega's
    (``tableau.omega_rank``): singular values at enough digits against the entries' uncertainty."""
    s = tab.s
    D = max(tab.decimal_digits or 0, tab.source_digits or 0)
    w = max(60, D + 30, 3 * s + 30)
    ent = tab.mp_entries(w)
    rad = 0.0
    radii = entry_radii(tab)
    with mpmath.workdps(w):
        om = mpmath.matrix(ent["omega"]) if s > 1 else None
        At = mpmath.matrix(ent["A_tilde"])
        bt = [x[0] if isinstance(x, list) else x for x in ent["b_tilde"]]
        N = mpmath.matrix(s, s)
        if s > 1:
            P = om * At
            for i in range(s - 1):
                for j in range(s):
                    N[i, j] = P[i, j]
        for j in range(s):
            N[s - 1, j] = bt[j]
        sv = sorted((float(x) for x in mpmath.svd_r(N, compute_uv=False)), reverse=True)
        if radii is not None:
            # ||Delta N||_F <= ||omega||_F ||Delta A_tilde||_F + ||Delta omega||_F ||A_tilde||_F + ||Delta b_tilde||
            fro = lambda M: float(mpmath.mnorm(M, "f"))
            # hypot: no overflow of the squares for entries up to MAX_MAGNITUDE
            dAt = math.hypot(*(x for r in radii["A_tilde"] for x in r))
            dbt = math.hypot(*radii["b_tilde"])
            dom = _omega_radius(tab)
            rad = (fro(om) * dAt + dom * fro(At) if s > 1 else 0.0) + dbt
    noise = s * s * 10.0 ** (5 - w) * max(sv[0], 1e-300)     # the SVD's backward error at w digits
    bound = rad + noise
    smin = sv[-1]
    how = f"mpmath singular values at dps {w} against the uncertainty {bound:.1e} of N"
    if smin > bound:
        return Check("solvable", PASS, smin, f"N = [omega A_tilde; b_tilde^T] is nonsingular (smallest singular "
                     f"value {smin:.3g} > {bound:.1e}): (21) determines V_i, Psi_i, v_1 for small h", how, bound)
    if smin > noise:
        # regular as written, singular only within the entries' uncertainty: the digits cannot tell
        # (Gauss-4 printed to 3 digits "was not solvable", smallest singular value 2.3e-3 within 3.0e-3)
        return Check("solvable", SKIP, smin, f"not decided at the precision of the entries: N = [omega A_tilde; "
                     f"b_tilde^T] as written is nonsingular (smallest singular value {smin:.3g}), but within their "
                     f"uncertainty {bound:.1e} it may be singular (give more digits); the numerical checks run on "
                     "the entries as written", how, bound)
    rank = sum(x > bound for x in sv)
    At_ = [[float(x) for x in r] for r in ent["A_tilde"]]
    explicit = all(abs(At_[i][j]) == 0 for i in range(s) for j in range(i, s))
    zero = all(abs(At_[i][j]) == 0 for i in range(s) for j in range(s)) and all(float(x) == 0 for x in bt)
    why = (" A_tilde = 0 and b_tilde = 0: the multipliers never enter (21b, d);" if zero else
           " A_tilde is explicit (strictly lower triangular): its last column is zero, so Psi_s enters (21b) "
           "nowhere and (21d) only through b_tilde_s, and the first stage's (21b) carries no multiplier at all;"
           if explicit else "")
    return Check("solvable", FAIL, smin,
                 f"(21) is not solvable for this tableau: N = [omega A_tilde; b_tilde^T] has rank {rank} < s = {s} "
                 f"(smallest singular value {smin:.2e}, within {bound:.1e}).{why} at h -> 0 the Newton matrix of "
                 "(21) is N (x) K M^-1 K^T after eliminating the velocities, so the multipliers Psi_i are not "
                 "determined: (21e), (21f) leave a direction of Psi free whatever the system", how, bound)


def _omega_radius(tab) -> float:
    """||Delta omega||_F, the uncertainty of omega (``tableau.omega_rank``)."""
    from ...core.tableau import omega_rank
    return omega_rank(tab)["radius"]


def check_22a(ar, e) -> Check:
    """(22a) b_hat_i = b_i."""
    with ar.context():
        items = [(e["b_hat"][i] - e["b"][i], f"i = {i + 1}") for i in range(len(e["b"]))]
        w, lab, ok, rad = _worst(ar, items)
    if ok:
        return Check("22a", PASS, w, f"b_hat = b {_mode(ar, w, rad)}", ar.label, _tol(ar, rad))
    return Check("22a", FAIL, w, f"b_hat_i != b_i, worst at {lab}: |b_hat_i - b_i| = {w:.3g}, "
                 f"{_beyond(ar, rad)}", ar.label, _tol(ar, rad))


def check_22b(ar, e) -> Check:
    """(22b) b_hat_i a_ij + b_j a_hat_ji - b_hat_i b_j = 0."""
    b, bh, A, Ah = e["b"], e["b_hat"], e["A"], e["A_hat"]
    s = len(b)
    with ar.context():
        items = [(bh[i] * A[i][j] + b[j] * Ah[j][i] - bh[i] * b[j], f"(i, j) = ({i + 1}, {j + 1})")
                 for i in range(s) for j in range(s)]
        w, lab, ok, rad = _worst(ar, items)
    if ok:
        return Check("22b", PASS, w, f"b_hat_i a_ij + b_j a_hat_ji = b_hat_i b_j for all i, j, {_mode(ar, w, rad)}",
                     ar.label, _tol(ar, rad))
    return Check("22b", FAIL, w, f"violated, worst at {lab}: |b_hat_i a_ij + b_j a_hat_ji - b_hat_i b_j| = {w:.3g}, "
                 f"{_beyond(ar, rad)}", ar.label, _tol(ar, rad))


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
            w, lab, ok, rad = _worst(ar, items)
            if ok:
                checks.append(Check(tag, PASS, w, f"{text} {_mode(ar, w, rad)}", ar.label, _tol(ar, rad)))
            else:
                checks.append(Check(tag, INFO, w, f"fails at {lab} (|residual| = {w:.3g}, {_beyond(ar, rad)}): "
                                    "the method is not symmetric", ar.label, _tol(ar, rad)))
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
                            f"(rooted trees to order {r.max_order}){more}", ar.label))
        checks.append(Check(f"simplifying:{M}", INFO, None,
                            f"B({sa['B']}), C({sa['C']}), D({sa['D']}) with nodes c", ar.label))
        checks.append(Check(f"stability:{M}", INFO, None,
                            f"R(inf) = {st.r_inf_str}" + (f" ({st.note})" if st.A_singular else
                                                          " (A invertible: 1 - b^T A^-1 1)")
                            + ("; L-stable-type damping" if st.r_inf == 0 else ""), ar.label))
    pr = oc.pair_order(ar, e["A"], e["b"], e["A_hat"], e["b_hat"])
    facts["order:pair"] = pr.order
    facts["order:pair-capped"] = pr.complete     # every tree checked holds: a lower bound
    more = "" if pr.failing is None else f"; first failing tree {pr.failing} (residual {pr.residual:.3g})"
    checks.append(Check("order:pair(A,A_hat)", INFO, pr.residual,
                        f"partitioned pair (A, b) for q' = v, (A_hat, b_hat) for p' = F: order "
                        f"{pr.order}{'+' if pr.complete else ''} (bi-coloured trees to order {pr.max_order}){more}", ar.label))
    so = oc.spark_ode_order(ar, e)
    facts["order:forced-ode"] = so.order
    facts["order:forced-ode-capped"] = so.complete
    more = "" if so.failing is None else f"; first failing tree {so.failing} (residual {so.residual:.3g})"
    checks.append(Check("order:forced-ode", INFO, so.residual,
                        f"(A; A_hat, A_tilde) on q' = v, p' = F + R with psi a given smooth forcing: order "
                        f"{so.order}{'+' if so.complete else ''} (coloured trees to order {so.max_order}){more}", ar.label))
    return checks, facts


# --- what the entries' uncertainty contributes to a numerical check ------------------------------
#: size of the probing perturbation (relative to the largest entry radius, scaled to this): far
#: above the working precision's noise (1e-15 at dps 30) so that the response is measured, far
#: below 1 so that it is linear (its quadratic part ~1e-20)
PERTURB = 1e-10
#: probing directions (pseudo-random signs, fixed seeds): with two, the largest response is below a
#: tenth of its root-mean-square in under 1 % of cases (two independent near-Gaussian sums)
ENTRY_SAMPLES = 2
#: the entries' actual deviation may align with the scene's sensitivity where a random direction
#: does not: a sum of n terms is at most sqrt(n) times its root-mean-square; a random-sign sample is
#: at least a tenth of that (ENTRY_SAMPLES): the bound is 10 sqrt(n) times the measured response
ENTRY_SAFETY = 10.0
#: the entries the audit moves: those whose balls the rank probe reads (``discrete._PROBED``)
PERTURBED = ("c", "A", "A_hat", "A_tilde", "b", "b_hat", "b_tilde")


def entry_radii(tab) -> dict | None:
    """The radius of every entry's ball (``SparkTableau.ball_entries``: decimals to the digits
    given, JSON numbers and float64 to half an ulp), as floats, vectors flat, omega left out;
    None when the entries are known exactly or computed to any precision (nothing to propagate)."""
    if tab.exact is None or tab.known_exactly:
        return None
    from ...analysis.discrete import entry_radii_of
    rad = entry_radii_of(tab)          # the rank probe's reading of the balls, not a second one
    umax = max(_flat(rad.values()), default=0.0)
    return rad if umax > 0 else None


def _flat(v):
    for x in v:
        if isinstance(x, (list, tuple)) or hasattr(x, "values"):
            yield from _flat(x.values() if hasattr(x, "values") else x)
        else:
            yield x


def perturbed_tableau(tab, radii: dict, eps: float, seed: int):
    """``tab`` with every entry moved by eps * (its radius / the largest radius) with a pseudo-random
    sign (``seed``): a tableau off by the shape of the entries' uncertainty, scaled to ``eps``."""
    import random
    umax = max(_flat(radii.values()))
    rng = random.Random(seed)
    dirs = {k: [[rng.choice((-1, 1)) * x / umax for x in r] if isinstance(r, list) else rng.choice((-1, 1)) * r / umax
                for r in v] for k, v in radii.items()}
    from ...analysis.discrete import moved_tableau
    return moved_tableau(tab, dirs, eps, "perturbed")


def entry_effect(tab, radii: dict, response) -> tuple[float, float]:
    """What the entries' uncertainty can contribute to a numerical quantity: ``response(T)`` is the
    quantity's change when the tableau is ``T`` instead of ``tab`` (a Theorem 1 residual, which
    vanishes under (22); a difference of final states). Measured on ENTRY_SAMPLES tableaux moved
    by PERTURB in the shape of the entries' radii, rescaled to the largest radius, times
    ENTRY_SAFETY sqrt(n) (``ENTRY_SAFETY``). Returns (bound, largest measured response per unit
    of perturbation)."""
    umax = max(_flat(radii.values()))
    n = sum(1 for _ in _flat(radii.values()))
    resp = max(float(response(perturbed_tableau(tab, radii, PERTURB, seed))) for seed in range(ENTRY_SAMPLES))
    return ENTRY_SAFETY * math.sqrt(n) * resp / PERTURB * umax, resp / PERTURB


def digits_of(residual: float, scale: float = 1.0) -> int:
    """The number of digits to which a quantity of size ``scale`` holds with this residual."""
    if residual <= 0:
        return 99
    ratio = residual / max(scale, 1e-300)
    if not math.isfinite(ratio):      # a residual or radius beyond float64 (entries of 1e155 squared)
        return 0
    return max(0, int(math.floor(-math.log10(ratio))))


# --- numerical checks ------------------------------------------------------------------------
def probe_step(tab: SparkTableau) -> None:
    """One float64 step on the skate and the particle; unusable tableau -> InputError."""
    from ...models.scenes import get_scene
    from ...core.spark import SparkMethod
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
    from ...core.spark import integrate
    t0, q0, v0 = scene.initial(dps)
    with mpmath.workdps(dps or 15):
        h = mpmath.mpf(t_end) / N if dps else t_end / N
        return integrate(scene.system, tab, t0, q0, v0, h, n_steps=N, dps=dps)


def _err(sol, qref, vref) -> float:
    dq = max(abs(float(x - y)) for x, y in zip(sol.q[-1], qref))
    dv = max(abs(float(x - y)) for x, y in zip(sol.v[-1], vref))
    return max(dq, dv)


def _reference_tableau(tab):
    """A Gauss SPARK method of order 2 max(5, s+1) >= 2s + 2, above any s-stage method's order 2s
    (Gauss-7 from a file has a reference too), and never the audited tableau itself."""
    from ...core.families import gauss
    from ...core.numbers import MAX_STAGES
    s = max(5, tab.s + 1)
    return gauss(s, max_stages=max(MAX_STAGES, s))     # one stage above the audited tableau's own bound


def observed_order(tab, scene_name, Ns, t_end, dps, floor):
    """Errors at t_end for N in Ns and the slope of the finest pair above the error floor."""
    from ...models.scenes import get_scene
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


#: errors used for a slope are at least this multiple of what the entries' uncertainty changes
ENTRY_FLOOR = 10.0


def _entry_floor_measured(tab, scene_name, N, t_end, wdps):
    """(ENTRY_FLOOR x what the entries' uncertainty changes in the state at t_end with N steps,
    the response per unit change): errors below it do not shrink like h^p (``entry_effect``);
    (0, 0) for exact entries."""
    from ...models.scenes import get_scene
    radii = entry_radii(tab)
    if radii is None:
        return 0.0, 0.0
    sc = get_scene(scene_name)
    base = _run(tab, sc, N, t_end, wdps)

    def change(T):
        sol = _run(T, sc, N, t_end, wdps)
        return _err(sol, base.q[-1], base.v[-1])
    _, per = entry_effect(tab, radii, change)
    umax = max(_flat(radii.values()))
    # the slope needs the typical size of the contamination, not its worst case: errors at least
    # ENTRY_FLOOR x the measured response to an uncertainty-sized change bend a slope by at most
    # log2((1 + 1/10) / (1 - 1/10)) = 0.29 < ORDER_SLACK
    return ENTRY_FLOOR * per * umax, per


def _floor_limited(res, floor) -> bool:
    """No slope of an ``observed_order`` result because its finest errors are at or below ``floor``:
    every error finite and the finest one <= floor (a NaN or infinite error is a failure of the run,
    not a floor), and not every error exactly zero (an error of exactly 0 at every step down to
    h = t_end is no accurate method but a comparison that compared nothing: a failure)."""
    errs = res["errors"]
    return (bool(errs) and all(math.isfinite(e) for e in errs) and errs[-1] <= floor
            and any(e != 0.0 for e in errs))


def convergence_checks(tab, predicted, dps, quick, capped=False):
    """Observed order on the skate (exact solution) and the particle (reference solution).
    One-sided (docs/audit.md): an observed order below the prediction fails; one above it is
    reported (the tree prediction is a lower bound of what a scene shows: an error constant can
    vanish on it), not failed. Errors below the working precision's floor, or below what the
    entries' own uncertainty can contribute (measured: ``_entry_floor_measured``), are not used
    for the slope; when that leaves no usable pair, coarser steps are added (down to h = t_end), also
    when the finest errors are below the working precision's floor (``_floor_limited``); none even
    there is undecided (info), while a NaN error or no slope above the floor fails."""
    checks, facts = [], {}
    # float64 suffices while the finest error stays far above round-off (order <= 4 at the
    # step counts below); higher orders run at dps digits
    wdps = None if predicted <= 4 else dps
    digits = 15 if wdps is None else dps
    wfloor = 10.0 ** (4 - digits)
    facts["convergence_dps"] = wdps
    kmax = 0.0
    for scene_name, t_end in (("skate", 1), ("particle", 1)):
        Ns = _step_counts(predicted, quick)
        try:
            try:
                efloor, eper = _entry_floor_measured(tab, scene_name, Ns[-1], t_end, wdps)
            except LdasparkError:      # a moved tableau's run failed: the working-precision floor only
                efloor, eper = 0.0, 0.0
            floor = max(wfloor, efloor)
            res = observed_order(tab, scene_name, Ns, t_end, wdps, floor)
            while not math.isfinite(res["observed"]) and (efloor > wfloor or _floor_limited(res, floor)) \
                    and Ns[0] >= 2:
                # the entries' floor reached: measure at coarser steps, down to one step of t_end (an
                # 8-digit Gauss-3 has only h = 1/2 above its floor on the skate); so too when the finest
                # errors are below the working precision's floor (Gauss-12 at dps 30: 4.9e-32 at h = 1/4
                # and 1/8 on the skate, an accurate method, not a failing one)
                try:
                    more = observed_order(tab, scene_name, [Ns[0] // 2] + Ns, t_end, wdps, floor)
                except LdasparkError:
                    break                   # the coarser step does not run: the finer result stands
                Ns, res = more["N"], more
        except LdasparkError as exc:   # e.g. Newton fails at the larger steps
            checks.append(Check(f"convergence:{scene_name}", FAIL, None,
                                f"integration failed: {str(exc).splitlines()[0]}"))
            continue
        kmax = max(kmax, res["max_constraint"])
        res["floor"], res["entry_floor"] = floor, efloor
        facts[f"convergence:{scene_name}"] = res
        obs = res["observed"]
        errs = ", ".join(f"h=1/{N}: {e:.2e}" for N, e in zip(res["N"], res["errors"]))
        fl = (f"; errors below {floor:.0e} not used (what the entries' uncertainty can contribute: a response "
              f"of {eper:.1e} per unit change of the entries, measured)" if efloor > wfloor else "")
        if not math.isfinite(obs) and efloor > wfloor:
            # every error that could give a slope is within what the entries' own uncertainty
            # changes: the digits given cannot show the order here (not a failure of the method)
            status, what = INFO, ("undecided: no slope above what the entries' uncertainty changes, down to "
                                  f"h = {t_end}/{res['N'][0]} (more digits in the file would decide it)")
        elif not math.isfinite(obs) and _floor_limited(res, floor):
            # no two errors above the arithmetic's floor, down to h = t_end / N_0: the method is more
            # accurate than the working precision can show (not a failure of it)
            status, what = INFO, (f"undecided: no slope above the working precision's floor {floor:.0e}, down to "
                                  f"h = {t_end}/{res['N'][0]} (a larger --dps would decide it)")
        elif not math.isfinite(obs):
            status, what = FAIL, "no usable slope (errors at the floor or zero)"
        elif obs < predicted - ORDER_SLACK:
            status, what = FAIL, f"observed {obs:.2f} below the predicted {predicted}"
        elif capped and obs > predicted + ORDER_SLACK:
            # the trees were checked up to the cap, so the prediction is ">= predicted", a lower bound
            status, what = PASS, f"observed {obs:.2f}, consistent with the prediction >= {predicted} (tree cap)"
        elif obs > predicted + ORDER_SLACK:
            # one-sided: faster than the trees predict is reported, not failed (the error constant
            # of the first failing tree can vanish on a scene)
            status, what = PASS, (f"observed {obs:.2f} above the predicted {predicted}: this scene converges "
                                  "faster than the trees predict (reported, not a failure: the check is one-sided)")
        else:
            status, what = PASS, f"observed {obs:.2f} vs predicted {predicted}"
        checks.append(Check(f"convergence:{scene_name}", status, abs(obs - predicted) if math.isfinite(obs) else None,
                            f"{what}; errors in (q, v) at t = {t_end} vs {res['reference']} "
                            f"({'float64' if wdps is None else f'dps {wdps}'}): {errs}{fl}"))
    ktol = 1e3 * (2.0 ** -52 if wdps is None else 10.0 ** (-wdps))
    checks.append(Check("constraint", PASS if kmax <= ktol else FAIL, kmax,
                        f"max |k(t_n, q_n, v_n)| over the convergence runs = {kmax:.2e} "
                        f"(tolerance {ktol:.0e}: (21f) imposes k = 0 at every step point)"))
    facts["max_constraint"] = kmax
    return checks, facts


def energy_check(tab, quick):
    """Energy error of the particle scene (E conserved, 8.1) on a short float64 run at h and
    h/2; information (the theorem says nothing quantitative about energy)."""
    from ...models.scenes import get_scene
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
