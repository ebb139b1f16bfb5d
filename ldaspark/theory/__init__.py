"""The theorem machinery: what the paper claims about SPARK methods, as computations.

discrete (discrete Lagrangian L_d(t0, q0, t1, q1) (13) as a function of the endpoints, Theorem 1
residuals, well-posedness of the boundary-value solve, symmetry (23)), conditions (exact (22),
(23)), order_conditions (trees), orders (observed orders, references), audit (``ldaspark audit``),
ledger (the claims ledger's records), flow_jacobian (Jacobian of the step map, ``ldaspark.flow_jacobian``),
bicycle_benchmark (the linearised benchmark bicycle of Meijaard et al. 2007, Appendix A) and
bicycle_flow (its eigenvalues from the SPARK flow).

Imports ``ldaspark.core`` only.
"""
