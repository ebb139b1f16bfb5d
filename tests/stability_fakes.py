"""Rows of the stability reports (stiff springs, tiny steps, round-off floor, extreme precision) and
a stand-in for ``ldaspark.compiled.fast``, shared by the rule tests of ``lab.reports.stability*``."""
from __future__ import annotations

import sys
import types

from ldaspark.lab.reports import stability_stiff as ss


def _stiff_row(scene, method, hw, cls, why="", rho=1.0, outcome=None, iterations=3.0, **kw):
    r = {"scene": scene, "method": method, "hw": hw, "h": hw / 100, "N": 1000, "class": cls, "why": why,
         "rho": rho, "R": None, "outcome": outcome or ("ok" if cls != "failed" else "NewtonError"),
         "iterations": iterations, "max_rel_dE": 1e-3 * hw, "generic_steps": None, "full_newton_steps": 0}
    if r["outcome"] != "ok":
        r.update(step=5, dE_before=kw.pop("dE_before", 1e-4), message="failed")
    r.update(kw)
    return r


def _stiff_rows():
    S = []
    for scene in ss.STIFF_SCENES:
        S += [_stiff_row(scene, "gauss-2", 0.1, "bounded", iterations=2.0),
              _stiff_row(scene, "gauss-2", 1.0, "bounded", iterations=4.0),
              _stiff_row(scene, "gauss-2", 3.0, "bounded", iterations=5.0),
              _stiff_row(scene, "gauss-2", 10.0, "bounded", iterations=6.0, generic_steps=2),
              _stiff_row(scene, "gauss-2", 100.0, "failed", "Newton"),
              _stiff_row(scene, "lobatto-iiia-iiib-2", 0.1, "bounded", iterations=1.5),
              _stiff_row(scene, "lobatto-iiia-iiib-2", 1.0, "growing", "energy growth", iterations=3.0),
              _stiff_row(scene, "lobatto-iiia-iiib-2", 1.9, "bounded", rho=1 + 1e-9),
              _stiff_row(scene, "lobatto-iiia-iiib-2", 2.1, "failed", "linear instability", rho=1.2),
              _stiff_row(scene, "lobatto-iiia-iiib-3", 3.0, "failed", "linear instability", rho=1.5),
              _stiff_row(scene, "lobatto-iiia-iiib-3", 10.0, "failed", "linear instability", rho=3.0,
                         dE_before=None)]
    return S


def _tiny_rows():
    rows = []
    for scene in ("skate", "robot"):
        for m in ("gauss-2", "euler-i"):
            for h in ss.TINY_H:
                if scene == "robot" and m == "euler-i" and h == 1e-5:
                    rows.append({"scene": scene, "method": m, "h": h, "N": 10 ** 4, "outcome": "NewtonError",
                                 "message": "no convergence"})
                else:
                    rows.append({"scene": scene, "method": m, "h": h, "N": 10 ** 4 if h > 1e-7 else 10 ** 5,
                                 "outcome": "ok", "max_dE": 1e-15 / h * 1e-6, "iterations": 2.0,
                                 "full_newton_steps": 2 if m == "gauss-2" and h == 1e-4 else 0,
                                 "generic_steps": 1 if h == 1e-6 else 0})
    return rows[:-2]          # the robot's euler-i at 1e-6 and 1e-7 missing: "-" cells


def _floor_rows():
    return [{"method": "gauss-1", "h": [1e-2, 1e-3, 1e-4], "N": [10, 100, 1000],
             "plain": [1e-6, 3e-12, 5e-11], "kahan": [1e-6, 2e-12, 1e-13]},
            {"method": "gauss-2", "h": [1e-2, 1e-3, 1e-4], "N": [10, 100, 1000],
             "plain": [4e-14, 1e-13, 9e-13], "kahan": [5e-14, 3e-15, 4e-15]}]


def _dps_rows():
    return [{"dps": 400, "N": 3, "seconds": 1.5, "iterations": 3.0, "log10_diff": -398.2, "ref_dps": 440},
            {"dps": 2000, "N": 3, "seconds": 9.0, "iterations": 3.0, "log10_diff": None, "ref_dps": 1960},
            {"dps": 100, "N": 2, "seconds": 0.5, "iterations": 2.0, "log10_diff": -120.4},      # older rows: no ref_dps
            {"dps": 60, "N": 2, "seconds": 0.5, "iterations": 2.0, "log10_diff": None}]


def _fake_fast(monkeypatch, fast_integrate=None, roundoff_errors=None):
    mod = types.ModuleType("ldaspark.compiled.fast")
    if fast_integrate is not None:
        mod.fast_integrate = fast_integrate
    if roundoff_errors is not None:
        mod.roundoff_errors = roundoff_errors
    monkeypatch.setitem(sys.modules, "ldaspark.compiled.fast", mod)
    return mod
