"""The theorem machinery: what the paper claims about SPARK methods, as computations.

discrete (discrete Lagrangian L_d(t0, q0, t1, q1) (13) as a function of the endpoints, Theorem 1
residuals, well-posedness of the boundary-value solve, symmetry (23)), conditions (exact (22),
(23)), order_conditions (trees), orders (observed orders, references), audit (``ldaspark audit``),
flow_jacobian (Jacobian of the step map, ``ldaspark.flow_jacobian``), bicycle_flow (the benchmark
bicycle's eigenvalues from the SPARK flow), definition1, section5, section7, variational and
energy_balance (the computations behind the claim groups of ``ldaspark.lab.claims``).

Imports ``ldaspark.core``, ``ldaspark.models`` and ``ldaspark.solve`` (and what they import).
"""
