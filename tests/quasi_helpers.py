"""The trajectory bound of the quasi-Newton root finder's tests (tests/compiled/test_kernels_quasi.py,
test_quasi_curvature.py, test_quasi_general.py): both root finders stop when the remaining error of
the step's unknowns is estimated at most lim = tol (|x| + |v0|) <= 8 eps * scale
(``newton.newton_status``, scale = max(1, |q|, |v|) over the run), so one step's results differ by at
most ~2 lim, and N steps of a non-expanding flow by at most 2 N 8 eps scale."""
import numpy as np

from ldaspark.compiled.kernels_quasi import QUASI_WAIT_MAX

EPS = float(np.finfo(float).eps)


def trajectory_difference(a, b):
    """max |dq|, |dv| over the run of Results a and b in units of 2 N * 8 eps * scale."""
    scale = max(1.0, float(np.abs(a.q).max()), float(np.abs(a.v).max()))
    d = max(float(np.abs(a.q - b.q).max()), float(np.abs(a.v - b.v).max()))
    return d / (2 * len(a.t) * 8 * EPS * scale)


def waits(n_steps, wait_max=QUASI_WAIT_MAX):
    """(attempts, skipped) of the quasi loops' wait rule when every attempt fails: after a failure
    the next `wait` steps go to the Newton chain, wait = backoff, backoff doubling up to wait_max
    (a Python model of IS_WAIT / IS_BACKOFF, ``kernels_quasi.QS_SKIPPED``)."""
    wait, backoff, attempts, skipped = 0, 1, 0, 0
    for _ in range(n_steps):
        if wait > 0:
            wait -= 1
            skipped += 1
        else:
            attempts += 1
            wait, backoff = backoff, min(2 * backoff, wait_max)
    return attempts, skipped
