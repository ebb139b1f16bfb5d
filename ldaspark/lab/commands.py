"""The paper lab's commands of ``ldaspark`` (registered as the entry point ``ldaspark.commands``
in pyproject.toml; the library's command line finds them there): module and help of each. A
command's module exposes ``add_arguments(parser)`` and ``run(args) -> int`` and is imported only
when its command runs."""

COMMANDS = {
    "report": ("ldaspark.lab.reports.driver", "write the reports (main job; no arguments = everything)"),
    "verify": ("ldaspark.lab.reports.claims", "run the theorem checks and write the claims ledger"),
    "audit": ("ldaspark.lab.theory.audit", "audit a tableau against Theorem 1's hypotheses and the numerics"),
    "mutants": ("ldaspark.lab.mutants.command",
                "plant catalogued faults one at a time and check the suite kills each"),
}
