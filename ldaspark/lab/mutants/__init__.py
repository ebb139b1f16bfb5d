"""The suite's proof of its teeth: the mutation catalogue (``ldaspark mutants``).

mutation_catalogue (the catalogue as data: ``Mutant``, ``CATALOGUE``, ``QUICK``), catalogue (one
module of mutants per area), mutation (plant each mutant in a scratch copy of the project and run
the suite against it).

Imports ``ldaspark.core`` and ``ldaspark.dist`` only: a mutant names its file and snippet as data.
"""
