"""The trajectory bound of the quasi-Newton root finder's tests (tests/compiled/test_kernels_quasi.py,
test_quasi_curvature.py, test_quasi_general.py): both root finders stop when the remaining error of
the step's unknowns is estimated at most lim = tol (|x| + |v0|) <= 8 eps * scale
(``newton.newton_status``, scale = max(1, |q|, |v|) over the run), so one step's results differ by at
most ~2 lim, and N steps of a non-expanding flow by at most 2 N 8 eps scale."""
import numpy as np

EPS = float(np.finfo(float).eps)


def trajectory_difference(a, b):
    """max |dq|, |dv| over the run of Results a and b in units of 2 N * 8 eps * scale."""
    scale = max(1.0, float(np.abs(a.q).max()), float(np.abs(a.v).max()))
    d = max(float(np.abs(a.q - b.q).max()), float(np.abs(a.v - b.v).max()))
    return d / (2 * len(a.t) * 8 * EPS * scale)
