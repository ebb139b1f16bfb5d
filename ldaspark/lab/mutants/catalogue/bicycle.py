"""Mutants of the Whipple bicycle (models/bicycle.py), its benchmark reference
(models/bicycle_benchmark.py) and the flow Jacobian (analysis/flow_jacobian.py)."""
from ..mutant import _m

VBIC = "verification/test_systems_bicycle.py"
TFJ = "tests/analysis/test_flow_jacobian.py"

MUTANTS = (
    _m("bicycle-trail-sign", "models/bicycle.py",
       'Fc = S0.locatenew("Fc", in_E(-p["c"], -p["rF"]))', 'Fc = S0.locatenew("Fc", in_E(p["c"], -p["rF"]))',
       "front wheel centre ahead of the steer axis' ground point: the trail's sign flipped", "system", VBIC),
    _m("bicycle-steer-axis-tilt-sign", "models/bicycle.py",
       'E = Ro.orientnew("E", "Axis", [theta + lam, Ro.y])', 'E = Ro.orientnew("E", "Axis", [theta - lam, Ro.y])',
       "steer axis tilted forward instead of back by lambda", "system", VBIC),
    _m("bicycle-rear-rolling-lever", "models/bicycle.py",
       "slip_R = Rc.vel(N) + Rw.ang_vel_in(N).cross(P.pos_from(Rc))",
       "slip_R = Rc.vel(N) + Rw.ang_vel_in(N).cross(Rc.pos_from(P))",
       "rear rolling constraint with the lever from the contact to the centre (wrong sign)", "system", VBIC),
    _m("benchmark-IAlx-zT", "models/bicycle_benchmark.py",
       "IAlx = -mA * uA * zA + ", "IAlx = -mA * uA * zT + ",
       "Appendix A: I_A lambda x with the whole bicycle's z_T instead of the front assembly's z_A", "system", VBIC),
    _m("flow-jacobian-transposed", "analysis/flow_jacobian.py",
       "return np.concatenate([dq1, dv1]), r.q1, r.v1", "return np.concatenate([dq1, dv1]).T, r.q1, r.v1",
       "flow Jacobian d(q1, v1)/d(q0, v0) transposed", "jacobian", TFJ),
    _m("flow-jacobian-no-p0-term", "analysis/flow_jacobian.py",
       "blk = st[i].L_vq - ini.L_vq", "blk = st[i].L_vq",
       "IFT: the dependence of p0 = grad_v L(q0, v0) on q0 left out of (21b)", "jacobian", TFJ),
    _m("flow-jacobian-tangent-sign", "analysis/flow_jacobian.py",
       "corr = bk.solve(Kd, -kv[:, j])", "corr = bk.solve(Kd, kv[:, j])",
       "restriction: dependent velocities moved against the linearised constraint", "jacobian", TFJ, VBIC),
)
