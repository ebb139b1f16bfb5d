"""What each kind of README mark is checked against (``ldaspark.lab.reports.summary.quote_kind``), on
synthetic values: no reports needed (so this file, unlike test_readme.py, runs in the mutants'
scratch copy, which has no reports/)."""


def test_quote_kinds_residual_class_and_timing_snapshot():
    """What each kind of mark is checked against, on synthetic values (no reports needed)."""
    from ldaspark.lab.reports.summary import quote_kind, quote_problem, same_magnitude
    assert [quote_kind(k) for k in ("run.wall", "wp.particle.ratios", "wp.skate.peer_ratios", "peers.robot.long",
                                    "energy.fig4.nh.seconds", "claims.general.max", "claims.theorem1.negctl_min",
                                    "claims.general", "convergence.spark", "wp.long.spark")] == \
        ["timing"] * 5 + ["residual"] * 2 + ["exact"] * 3
    # residuals: the same order of magnitude (within a factor 10) passes, another fails
    assert same_magnitude("6.3e-17", "9.9e-17") and same_magnitude("9.9e-17", "1.0e-17")
    assert not same_magnitude("6.3e-17", "6.4e-16") and not same_magnitude("1.4e-40", "1.4e-17")
    assert quote_problem("claims.general.max", "6.3e-17", {"claims.general.max": "9.9e-17"}) is None
    assert "order of magnitude" in quote_problem("claims.general.max", "6.3e-17", {"claims.general.max": "2.0e-15"})
    # exact keys: equal text only
    assert quote_problem("claims.general", "94 of 94", {"claims.general": "94 of 94"}) is None
    assert quote_problem("claims.general", "94 of 94", {"claims.general": "93 of 94"}) is not None
    # timings: against the snapshot, whatever the new run measured
    snap = {"values": {"wp.particle.ratios": "9x / 8x / 7x"}}
    assert quote_problem("wp.particle.ratios", "9x / 8x / 7x", {"wp.particle.ratios": "14x / 19x / 16x"},
                         snap=snap) is None
    assert "snapshot" in quote_problem("wp.particle.ratios", "14x / 19x / 16x", {"wp.particle.ratios": "14x / 19x / 16x"},
                                       snap=snap)
    assert "no snapshot" in quote_problem("wp.particle.ratios", "9x / 8x / 7x", {}, snap={"values": {}})


def test_roundoff_driven_fig4_exponents_are_checked_against_the_snapshot():
    """The Fig. 4 drift exponents are a random walk of round-off (a fresh run moved 1.31 to 0.64):
    README's values must equal the committed run's snapshot, not a new run's; the printed
    scene's verdict (exponents ~0.01, far from 1) and the counts of other reports stay exact."""
    from ldaspark.lab.reports.summary import quote_kind, quote_problem
    assert [quote_kind(k) for k in ("energy.fig4.nh.exponents", "energy.fig4.nh.near1", "energy.fig4.nh.verdict",
                                    "energy.fig4.printed.exponents", "energy.fig4.printed.verdict",
                                    "energy.fig4.printed.near1", "energy.figs13.bounded")] == \
        ["timing"] * 4 + ["exact"] * 3
    snap = {"values": {"energy.fig4.nh.exponents": "1.310, 1.148, 0.393"}}
    fresh = {"energy.fig4.nh.exponents": "0.643, 1.066, 0.717"}
    assert quote_problem("energy.fig4.nh.exponents", "1.310, 1.148, 0.393", fresh, snap=snap) is None
    assert "snapshot" in quote_problem("energy.fig4.nh.exponents", "0.643, 1.066, 0.717", fresh, snap=snap)
