"""The paper lab: what this repository does with the library ``ldaspark`` to check Jay's paper.

theory (the computations behind the claim groups: sections 5 and 7, Definition 1, the energy
balance, the exact flow, variational orders, observed orders, the tableau audit), claims (the
claims ledger, ``ldaspark verify``), mutants (the mutation catalogue and generated mutants,
``ldaspark mutants``), reports (the main job, ``ldaspark report``) and commands (how these join
the command line). The lab imports the library; the library never imports the lab
(``tests/project/test_layers.py``).
"""
