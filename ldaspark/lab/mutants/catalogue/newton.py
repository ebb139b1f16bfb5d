"""Mutants of the Newton stopping rule and its fallback chain: compiled/newton.py,
compiled/kernels.py, compiled/fast.py, core/backend.py; tests/core/test_newton_stopping.py."""
from ..mutant import _m

TNS = "tests/core/test_newton_stopping.py"

MUTANTS = (
    _m("newton-lim-absolute", "compiled/newton.py",
       "lim = tol * (xn + scale)", "lim = tol * (xn + 1.0)",
       "compiled Newton limit with an absolute term instead of the round-off scale |v0| of the stage values "
       "(not invariant under the scale of the state)", "compiled", TNS),
    _m("newton-lim-increments-only", "compiled/newton.py",
       "lim = tol * (xn + scale)", "lim = tol * (xn + 0.0 * scale)",
       "compiled Newton limit relative to the increments x only (below the rounding of V_i = v0 + Z_i at "
       "small h: the reported tiny-step failure)", "compiled", TNS),
    _m("newton-rate-test-removed", "compiled/newton.py",
       "if theta < 1.0 and theta / (1.0 - theta) * dn <= RATE_KAPPA * lim:",
       "if theta < 0.0:",
       "RADAU5's rate test theta / (1 - theta) |dx| <= kappa lim removed from the compiled stopping rule",
       "compiled", TNS),
    _m("newton-rate-one-ratio", "compiled/newton.py",
       "if theta_prev > 0.0:\n        theta = np.sqrt(theta_k * theta_prev)",
       "if True:\n        theta = theta_k",
       "rate test on the last ratio alone (one sudden drop of |dx| taken as convergence)", "compiled", TNS),
    _m("newton-noise-without-exact-matrix", "compiled/newton.py",
       "if exact and theta_k >= 0.5 and dn <= NOISE_FACTOR * lim:",
       "if theta_k >= 0.5 and dn <= NOISE_FACTOR * lim:",
       "stalled increments accepted as round-off noise also with a stale (simplified) Newton matrix",
       "compiled", TNS),
    _m("newton-full-fallback-skipped", "compiled/kernels.py",
       "        if status != 1:\n            have = False\n            # fallback: full Newton from the generic",
       "        if False:\n            have = False\n            # fallback: full Newton from the generic",
       "the kernel's full-Newton fallback skipped (simplified Newton failure is final)", "compiled", TNS),
    _m("newton-generic-rescue-skipped", "compiled/fast.py",
       "        from .rescue import run_with_rescue\n        return run_with_rescue(",
       "        from .rescue import run_with_rescue\n        raise exc\n        return run_with_rescue(",
       "the generic full-Newton step as last fallback skipped (a kernel failure is final)", "compiled", TNS),
    _m("newton-eps-from-float64", "core/backend.py",
       "return float(e) if self.dps <= EPS_FLOAT_DPS else e", "return float(e)",
       "unit round-off of the mpmath precision rounded to float64 (0.0 at dps >= 324)", "system", TNS),
)

MUTANTS = MUTANTS + (
    _m("newton-reuse-p0-stale", "compiled/kernels_general.py",
       "    model[1](t0, q0, v0, ws[27], ws[17], ws[18], ws[19])\n",
       "    return\n",
       "a step that reuses the Newton matrix keeps the previous step's p0 (general form)", "compiled",
       "tests/compiled/test_newton_reuse.py"),
    _m("newton-reuse-no-theta-bound", "compiled/kernels.py",
       "have = status == 1 and stats[3] - nj <= 1 and worst <= REUSE_THETA",
       "have = status == 1 and stats[3] - nj <= 1",
       "the previous step's Newton matrix kept however slowly it contracts", "compiled",
       "tests/compiled/test_newton_reuse.py"),
)
