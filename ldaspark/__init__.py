"""ldaspark: Lagrange-d'Alembert SPARK integrators for nonholonomic Lagrangian systems (Jay)."""
