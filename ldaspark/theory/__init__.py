"""The theorem machinery: what the paper claims about SPARK methods, as computations.

discrete (discrete Lagrangian L_d(t0, q0, t1, q1) (13) as a function of the endpoints, Theorem 1
residuals, well-posedness of the boundary-value solve, symmetry (23)), conditions (exact (22),
(23)), order_conditions (trees), orders (observed orders, references), audit (``ldaspark audit``),
ledger (the claims ledger's records).

Imports ``ldaspark.core`` only.
"""
