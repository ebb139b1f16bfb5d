"""The claims ledger: the paper's claims as records with a verdict, written by ``ldaspark verify``.

ledger (the (tableau, scene) checks of Theorem 1, (22), (23) and 5.1, the record format, the
claim groups and where their units run), claims_general (the general and classic systems),
claims_paper (sections 2.2, 4, 5 and 7), claims_index (every numbered equation and claim sentence
of the paper with the test that checks it). The computations themselves live in
``ldaspark.lab.theory``.

Imports ``ldaspark.lab.theory`` and the layers below it.
"""
