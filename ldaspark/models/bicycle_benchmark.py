"""The linearised benchmark bicycle of Meijaard, Papadopoulos, Ruina and Schwab (2007), from the
formulas of its Appendix A: an independent reference for the SPARK flow of the Whipple bicycle
(``ldaspark.models.bicycle``), which it shares nothing with but Table 1.

Source: J. P. Meijaard, J. M. Papadopoulos, A. Ruina and A. L. Schwab, "Linearized dynamics
equations for the balance and steer of a bicycle: a benchmark and review", Proc. R. Soc. A 463
(2007) 1955-1982. The lean phi and steer delta about upright straight running at forward speed v
obey (their eq. 5.3, no applied torques)

    M q'' + v C1 q' + (g K0 + v^2 K2) q = 0,    q = (phi, delta),

with M, C1, K0, K2 from the parameters of Table 1 by the formulas of Appendix A (eqs. A 1-A 27,
evaluated below in that order). The eigenvalues lambda are the roots of
det(M lambda^2 + v C1 lambda + g K0 + v^2 K2) = 0 (a quartic). ``PUBLISHED`` holds the
benchmark's printed values (the matrices of eq. 5.4 and the eigenvalues and speeds of Table 2)
so that this implementation is itself checked against the paper.
"""
from __future__ import annotations

import mpmath

#: printed values of the benchmark (eq. 5.4 matrices; Table 2: eigenvalues at v = 0 and 5 m/s,
#: the weave and capsize speeds), 14 significant digits as printed
PUBLISHED = {
    "M": (("80.81722", "2.31941332208709"), ("2.31941332208709", "0.29784188199686")),
    "C1": (("0", "33.86641391492494"), ("-0.85035641456978", "1.68540397397560")),
    "K0": (("-80.95", "-2.59951685249872"), ("-2.59951685249872", "-0.80329488458618")),
    "K2": (("0", "76.59734589573222"), ("0", "2.65431523794604")),
    "eig_v0": ("-5.53094371765393", "-3.13164324790656", "3.13164324790656", "5.53094371765393"),
    "eig_v5": ("-14.07838969279822", ("-0.77534188219585", "-4.46486771378823"),
               ("-0.77534188219585", "4.46486771378823"), "-0.32286642900409"),
    "v_weave": "4.29238253634111",
    "v_capsize": "6.02426201538837",
}

#: Table 1 as decimal strings (exact at any precision; lambda = pi/10 is set below)
TABLE1 = {
    "w": "1.02", "c": "0.08", "g": "9.81",
    "rR": "0.3", "mR": "2", "IRxx": "0.0603", "IRyy": "0.12",
    "xB": "0.3", "zB": "-0.9", "mB": "85", "IBxx": "9.2", "IByy": "11", "IBzz": "2.8", "IBxz": "2.4",
    "xH": "0.9", "zH": "-0.7", "mH": "4", "IHxx": "0.05892", "IHyy": "0.06", "IHzz": "0.00708",
    "IHxz": "-0.00756",
    "rF": "0.35", "mF": "3", "IFxx": "0.1405", "IFyy": "0.28",
}


def matrices(dps: int = 30, **overrides):
    """(M, C1, K0, K2, g) as mpmath matrices at ``dps`` digits from Table 1 (``overrides``:
    parameter name -> decimal string or number, e.g. c="-0.08" for the trail-sign control)."""
    with mpmath.workdps(dps + 10):
        P = {k: mpmath.mpf(v) for k, v in TABLE1.items()}
        P["lam"] = mpmath.pi / 10
        for key, val in overrides.items():
            if key not in P:
                raise KeyError(f"unknown benchmark parameter {key!r}")
            P[key] = mpmath.mpf(val)
        w, c, lam, g = P["w"], P["c"], P["lam"], P["g"]
        rR, mR, IRxx, IRyy = P["rR"], P["mR"], P["IRxx"], P["IRyy"]
        xB, zB, mB, IBxx, IBzz, IBxz = P["xB"], P["zB"], P["mB"], P["IBxx"], P["IBzz"], P["IBxz"]
        xH, zH, mH, IHxx, IHzz, IHxz = P["xH"], P["zH"], P["mH"], P["IHxx"], P["IHzz"], P["IHxz"]
        rF, mF, IFxx, IFyy = P["rF"], P["mF"], P["IFxx"], P["IFyy"]
        sl, cl = mpmath.sin(lam), mpmath.cos(lam)
        # (A 1-A 7) the whole bicycle T
        mT = mR + mB + mH + mF
        xT = (xB * mB + xH * mH + w * mF) / mT
        zT = (-rR * mR + zB * mB + zH * mH - rF * mF) / mT
        ITxx = IRxx + IBxx + IHxx + IFxx + mR * rR ** 2 + mB * zB ** 2 + mH * zH ** 2 + mF * rF ** 2
        ITxz = IBxz + IHxz - mB * xB * zB - mH * xH * zH + mF * w * rF
        IRzz, IFzz = IRxx, IFxx
        ITzz = IRzz + IBzz + IHzz + IFzz + mB * xB ** 2 + mH * xH ** 2 + mF * w ** 2
        # (A 8-A 13) the front assembly A = H + F
        mA = mH + mF
        xA = (xH * mH + w * mF) / mA
        zA = (zH * mH - rF * mF) / mA
        IAxx = IHxx + IFxx + mH * (zH - zA) ** 2 + mF * (rF + zA) ** 2
        IAxz = IHxz - mH * (xH - xA) * (zH - zA) + mF * (w - xA) * (rF + zA)
        IAzz = IHzz + IFzz + mH * (xH - xA) ** 2 + mF * (w - xA) ** 2
        # (A 14-A 17) about the steer axis
        uA = (xA - w - c) * cl - zA * sl
        IAll = mA * uA ** 2 + IAxx * sl ** 2 + 2 * IAxz * sl * cl + IAzz * cl ** 2
        IAlx = -mA * uA * zA + IAxx * sl + IAxz * cl
        IAlz = mA * uA * xA + IAxz * sl + IAzz * cl
        # (A 18-A 22) trail ratio and gyrostatic coefficients
        mu = c / w * cl
        SR, SF = IRyy / rR, IFyy / rF
        ST = SR + SF
        SA = mA * uA + mu * mT * xT
        # (A 23-A 27) the matrices
        M = mpmath.matrix([[ITxx, IAlx + mu * ITxz], [IAlx + mu * ITxz, IAll + 2 * mu * IAlz + mu ** 2 * ITzz]])
        K0 = mpmath.matrix([[mT * zT, -SA], [-SA, -SA * sl]])
        K2 = mpmath.matrix([[0, (ST - mT * zT) / w * cl], [0, (SA + SF * sl) / w * cl]])
        C1 = mpmath.matrix([[0, mu * ST + SF * cl + ITxz / w * cl - mu * mT * zT],
                            [-(mu * ST + SF * cl), IAlz / w * cl + mu * (SA + ITzz / w * cl)]])
    return M, C1, K0, K2, g


def state_matrix(v, dps: int = 30, **overrides):
    """A(v) of x' = A x, x = (phi, delta, phi', delta'): [[0, I], [-M^-1 (g K0 + v^2 K2), -M^-1 v C1]]."""
    with mpmath.workdps(dps + 10):
        M, C1, K0, K2, g = matrices(dps, **overrides)
        v = mpmath.mpf(v)
        Mi = M ** -1
        Kv = -Mi * (g * K0 + v ** 2 * K2)
        Cv = -Mi * (v * C1)
        A = mpmath.zeros(4, 4)
        A[0, 2] = A[1, 3] = 1
        for i in range(2):
            for j in range(2):
                A[2 + i, j] = Kv[i, j]
                A[2 + i, 2 + j] = Cv[i, j]
    return A


def eigenvalues(v, dps: int = 30, **overrides) -> list:
    """The four eigenvalues of the linearised bicycle at speed v, sorted by (real, imaginary)
    part, as mpmath mpc at ``dps`` digits."""
    with mpmath.workdps(dps + 10):
        ev = mpmath.eig(state_matrix(v, dps, **overrides), left=False, right=False)
        ev = [mpmath.mpc(e) for e in ev]
        return sorted(ev, key=lambda z: (float(z.real), float(z.imag)))


def max_real_part(v, dps: int = 30, **overrides):
    return max(e.real for e in eigenvalues(v, dps, **overrides))


def _weave_function(v, dps, **overrides):
    """Real part of the weave pair (the complex pair) at speed v."""
    pair = [e for e in eigenvalues(v, dps, **overrides) if abs(e.imag) > 1e-20]
    return pair[0].real


def critical_speeds(dps: int = 30, **overrides):
    """(v_weave, v_capsize): the speeds where the weave pair and the capsize eigenvalue cross
    the imaginary axis (self-stable between them), by secant iteration at ``dps`` digits."""
    with mpmath.workdps(dps + 10):
        vw = mpmath.findroot(lambda v: _weave_function(v, dps, **overrides), (mpmath.mpf(4), mpmath.mpf("4.5")),
                             solver="secant")

        def capsize(v):       # the real eigenvalue nearest 0 (the capsize mode)
            reals = [e.real for e in eigenvalues(v, dps, **overrides) if abs(e.imag) <= 1e-20]
            return max(reals)
        vc = mpmath.findroot(capsize, (mpmath.mpf(6), mpmath.mpf("6.1")), solver="secant")
    return vw, vc
