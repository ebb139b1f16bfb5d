"""Mutants of the classic nonholonomic systems (``models/systems_classic.py``) and their report
section (``lab/reports/systems.py``): a sign in a scene's L or k, a wrong closed form or invariant, a
wrong verdict of the report."""
from ..mutant import _m

SLE = "verification/test_systems_chaplygin_sleigh.py"
DSK = "verification/test_systems_tilted_disk.py"
SPH = "verification/test_systems_chaplygin_sphere.py"
SUS = "verification/test_systems_suslov.py"
COS = "verification/test_systems_contact_oscillator.py"
BAL = "verification/test_systems_ball_turntable.py"
REP = "tests/lab/reports/test_systems_report.py"
SC = "models/systems_classic.py"

MUTANTS = (
    _m("systems-sleigh-com-behind", SC, 'G = P.locatenew("G", a * B.x)', 'G = P.locatenew("G", -a * B.x)',
       "Chaplygin sleigh: centre of mass behind the blade (a sign in L)", "system", SLE),
    _m("systems-sleigh-closed-form-rate", SC, "kap = omega0 / 2", "kap = omega0 / 3",
       "Chaplygin sleigh: wrong rate kappa of the tanh / sech closed form", "system", SLE),
    _m("systems-disk-rolling-sign", SC, "vc = D.vel(N) + C.ang_vel_in(N).cross(-r * B.z)",
       "vc = D.vel(N) + C.ang_vel_in(N).cross(r * B.z)",
       "tilted disk: rolling constraint at the top of the disk (a sign in k)", "system", DSK),
    _m("systems-disk-steady-sign", SC, "-(4 * g + 5 * r * Omega ** 2 * sympy.cos(theta0))",
       "-(4 * g - 5 * r * Omega ** 2 * sympy.cos(theta0))",
       "tilted disk: a sign in the steady-motion spin (closed form)", "system", DSK),
    _m("systems-sphere-M-sign", SC, "Ms = [Ii * wi + m * r ** 2 * (wi - wg * gi)",
       "Ms = [Ii * wi + m * r ** 2 * (wi + wg * gi)",
       "Chaplygin sphere: wrong angular momentum about the contact point (invariant)", "system", SPH),
    _m("systems-suslov-kappa", SC, "kap = I13 * W / I1", "kap = I13 * W / I2",
       "Suslov: wrong rate of the tanh / sech closed form", "system", SUS),
    _m("systems-contact-constraint", SC, "k = [v[0] + q[1] * v[2]]", "k = [v[0] + q[1] * v[1]]",
       "contact oscillator: x' + y y' (the y-energy is no longer a first integral)", "system", COS),
    _m("systems-ball-kappa", SC, "beta = R(2, 7) * Theta", "beta = R(2, 5) * Theta",
       "ball on a turntable: centre angular velocity 2 Omega / 5 instead of 2 Omega / 7", "system", BAL),
    _m("systems-ball-table-sign", SC, "table = Om_t * N.z.cross(x * N.x + y * N.y)",
       "table = -Om_t * N.z.cross(x * N.x + y * N.y)",
       "ball on a turntable: the table turning the other way in k", "system", BAL),
    _m("systems-report-bounded-verdict", "lab/reports/systems.py", '"bounded": bool(rnd or r <= BOUNDED_RATIO)',
       '"bounded": bool(rnd or r >= BOUNDED_RATIO)',
       "systems report: bounded when the error grows", "orders", REP),
)
