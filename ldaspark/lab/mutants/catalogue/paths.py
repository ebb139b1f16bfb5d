"""Mutants of the paths that must agree (issue 49's classes, written by hand in code changed in
round 5, by someone who had not seen it): an option dropped on one engine or one path, a cache
that serves another method's numbers, the clock of a run started at t0 != 0 (chunks, the
guard's reruns, the failing step's examination, the quasi-Newton kernel), psi rows of the
wrong step, ensembles and executors, the guard's window and rerun, the checkpoint fingerprint,
the mutation tool's verdict on a file-level error and the ratios quoted in the README."""
from ..mutant import _m

TRF = "tests/core/test_rootfinder.py"
TOB = "tests/api/test_options_observable.py"
TQ = "tests/compiled/test_kernels_quasi.py"
TQG = "tests/compiled/test_quasi_general.py"
TDF = "tests/compiled/test_diagnose_failure.py"
TEP = "tests/api/test_engine_protocol.py"
TPA = "tests/api/test_paths_agree.py"
TPSI = "tests/api/test_psi_everywhere.py"
TPROP = "tests/api/test_api_properties.py"
TG = "tests/core/test_guard.py"
TGE = "tests/core/test_guard_edges.py"
TENS = "tests/ensemble/test_ensemble.py"
TENG = "tests/ensemble/test_ensemble_guard.py"
TDASK = "tests/ensemble/test_executors_dask.py"
TCK = "tests/lab/test_checkpoint.py"
TCKR = "tests/lab/mutants/test_checkpoint_records.py"
TCLS = "tests/lab/mutants/test_mutgen_classify.py"
TRM = "tests/project/test_readme.py"
TSP = "tests/compiled/test_specialised.py"

MUTANTS = (
    # --- the root finder: a field dropped on one engine ----------------------------------------
    _m("paths-generic-predictor-dropped", "engines/generic.py",
       "n_steps, predictor=prepared.root.predictor):", "n_steps, predictor=\"auto\"):",
       "the generic engine ignores Newton(predictor=...) (accepted, validated, not run)", "paths",
       TRF + "::test_predictor_zero_changes_the_iterations", TRF),
    _m("paths-generic-max-iter-dropped", "engines/generic.py",
       "                             max_iter=root.iterations)", "                             max_iter=50)",
       "the generic engine runs 50 iterations whatever Newton(max_iter=...) says", "paths",
       TRF + "::test_tol_and_max_iter_are_honoured", TRF),
    _m("paths-comparator-max-iter-dropped", "engines/comparator.py",
       "dps=o.dps, tol=o.tol, max_stages=o.max_stages, max_iter=root.iterations)",
       "dps=o.dps, tol=o.tol, max_stages=o.max_stages, max_iter=50)",
       "the comparator engine ignores Newton(max_iter=...)", "paths",
       TRF + "::test_the_semi_implicit_kernel_and_the_comparators_refuse_in_one_line", TRF),
    _m("paths-comparator-tol-dropped", "engines/comparator.py",
       "dps=o.dps, tol=o.tol, max_stages=o.max_stages, max_iter=root.iterations)",
       "dps=o.dps, tol=None, max_stages=o.max_stages, max_iter=root.iterations)",
       "the comparator engine ignores tol (its runs stop at the default tolerance)", "paths",
       TRF + "::test_a_comparator_honours_tol", TRF),
    _m("paths-newton-object-tol-dropped", "core/rootfinder.py",
       "return newton if tol is None or newton.tol is not None else dataclasses.replace(newton, tol=tol)",
       "return newton",
       "integrate(newton=Newton(...), tol=x) drops tol (only the kind names took it)", "paths",
       TRF + "::test_a_newton_object_takes_the_tol_given_to_integrate", TRF),
    _m("paths-quasi-max-iter-dropped", "compiled/quasi.py",
       "opts.max_iter if opts.max_iter is not None else 50, predictor)", "50, predictor)",
       "newton kind 'quasi' runs 50 iterations whatever max_iter says", "paths",
       TRF + "::test_the_quasi_kind_honours_max_iter", TRF, TQ),
    # --- a cache serving another method -------------------------------------------------------
    _m("paths-quasi-predictor-cache-by-size", "compiled/quasi.py",
       "key = what[0].tobytes()", "key = len(what[0])",
       "the quasi-Newton collocation predictor's weights cached by the stage count: lobatto-iiia-iiib-2 "
       "run after gauss-2 extrapolates with gauss-2's nodes", "paths",
       TQ + "::test_the_collocation_predictor_is_the_one_of_the_method_run", TQ),
    # --- the clock of a run from t0 != 0 ------------------------------------------------------
    _m("paths-quasi-general-t0-dropped", "compiled/quasi.py",
       "entry(\"general\")(cs.model, what, cs.M, ex[0], ex[1], float(t0),",
       "entry(\"general\")(cs.model, what, cs.M, ex[0], ex[1], 0.0,",
       "the general-form quasi-Newton kernel started at t = 0 whatever t0", "paths",
       TQG + "::test_random_general_systems_agree_with_newton", TQG),
    _m("paths-quasi-stage-clock-from-zero", "compiled/kernels_quasi.py",
       "        t = t0 + step * h\n", "        t = step * h\n",
       "the mechanical quasi-Newton kernel's stage times k h + c_i h, without t0 (the saved times "
       "stay right)", "paths",
       TQ + "::test_a_rheonomic_scene_started_at_t0_not_zero_agrees_with_newton", TQ),
    _m("paths-quasi-rate-span-dropped", "compiled/kernels_quasi.py",
       "and dref <= RATE_SPAN * dn and dn <= RATE_SPAN * dref):", "):",
       "the mechanical quasi-Newton kernel's carried rate applied to a first increment of any size "
       "(particle gauss-6, tol = 1e-8: one step off by 1.6e-7)", "paths",
       TQ + "::test_a_carried_rate_is_applied_only_to_first_increments_of_its_size", TQ),
    _m("paths-quasi-general-rate-span-dropped", "compiled/kernels_quasi_general.py",
       "and dref <= RATE_SPAN * dn and dn <= RATE_SPAN * dref):", "):",
       "the general quasi-Newton kernel's carried rate applied to a first increment of any size "
       "(ball-turntable gauss-5, tol = 1e-12: 5x the bound)", "paths",
       TQ + "::test_a_carried_rate_is_applied_only_to_first_increments_of_its_size", TQ),
    _m("paths-tol-below-round-off-accepted", "core/options.py",
       "validate.check_tol_resolvable(tol, dps)", "None",
       "integrate accepts a tol below the unit round-off and each engine does something else with it",
       "paths", "tests/core/test_newton_stopping.py::test_a_tol_below_the_unit_round_off_is_refused_by_every_engine",
       "tests/core/test_newton_stopping.py"),
    _m("paths-compiled-explain-t0-dropped", "engines/compiled.py",
       "tk = float(t0) + k * float(h)", "tk = k * float(h)",
       "a compiled Newton failure examined (and reported) at k h instead of t0 + k h", "paths",
       TDF + "::test_the_failing_step_is_examined_at_its_own_time_when_t0_is_not_zero", TDF),
    _m("paths-chunk-error-time-t0-dropped", "core/chunks.py",
       "exc.time = t0f + exc.step * hf", "exc.time = exc.step * hf",
       "a failure in a block of a chunked run reported at k h instead of t0 + k h", "paths",
       TEP + "::test_a_failure_in_a_later_block_names_the_step_and_time_of_the_whole_run", TEP),
    _m("paths-chunk-long-every-not-aligned", "core/chunks.py",
       "else min(n - done, chunk, (done // b + 1) * b - done)", "else min(n - done, chunk)",
       "save_every longer than a block: block ends no longer fall on the saved points", "paths",
       TPSI + "::test_chunked_runs_keep_the_psi_of_their_saved_steps", TPSI),
    # --- the driver's monitors and psi rows ----------------------------------------------------
    _m("paths-watch-prev-not-kept", "solve.py",
       "        self.prev = (st.V, st.Psi, self.h)", "        self.prev = None",
       "the generic engine's guard never re-solves from the previous step's collocation polynomial",
       "paths", TG + "::test_a_second_root_stops_the_run_on_every_engine", TG),
    _m("paths-watch-energy-from-start", "solve.py",
       "        self.Ex, self.E = st.energy, E1\n        self.prev", "        self.prev",
       "the stepping engines' energy monitor and guard compare each step with the initial energy",
       "paths", TPA + "::test_energy_monitor_sees_every_step_with_save_every", TPA, TG),
    _m("paths-steps-psi-of-step-ending", "solve.py",
       "            if i % every == 0:\n                Ps.append(st.Psi)",
       "            if (i + 1) % every == 0:\n                Ps.append(st.Psi)",
       "generic engine with save_every: the psi of the step ending at a saved point instead of the one "
       "starting there", "paths", TPROP + "::test_integrate_returns_finite_result_or_one_error", TPSI, TPROP),
    _m("paths-post-process-psi-of-step-ending", "solve.py",
       "        full.psi = np.asarray(full.psi)[idx[:-1]]", "        full.psi = np.asarray(full.psi)[idx[1:] - 1]",
       "block engines sliced by the driver: the psi of the step ending at a saved point", "paths",
       TPSI + "::test_dense_output_and_events_keep_psi", TPSI),
    _m("paths-energy-jump-psi-row-extra", "solve.py",
       "        res.psi = np.asarray(res.psi)[:k]", "        res.psi = np.asarray(res.psi)[:k + 1]",
       "a run cut by the energy monitor keeps the psi of the step that jumped", "paths",
       TPA + "::test_ensemble_members_equal_their_single_runs", TPA, TPSI),
    # --- ensembles and executors ---------------------------------------------------------------
    _m("paths-compiled-ensemble-events-dropped", "solve.py",
       "opts.dense_output or opts.events or opts.project", "opts.dense_output or opts.project",
       "an initial-data ensemble with an executor and guard=False goes to the kernel tasks with "
       "events, which they do not locate", "paths",
       TPA + "::test_executor_kernel_tasks_equal_their_single_runs", TPA),
    _m("paths-run-plan-by-spec", "ensemble.py",
       "results[k].extend(res[names[i]] if check is None else check(res[names[i]], args, executor))",
       "results[k].extend(res[names[k]] if check is None else check(res[names[k]], args, executor))",
       "run_many assembles each spec from the unit named after the spec, not its own units", "paths",
       TENS + "::test_process_pool_matches_serial", TENS),
    _m("paths-ensemble-rerun-t0-dropped", "ensemble.py",
       "                self.t0, q0, v0, n_steps, 1, boundaries=self.every)",
       "                0.0, q0, v0, n_steps, 1, boundaries=self.every)",
       "the guard's rerun of an ensemble member starts at t = 0 (a rheonomic member is judged on "
       "another trajectory)", "paths", TENG + "::test_the_guard_reruns_a_member_from_its_own_t0", TENG),
    _m("paths-ensemble-task-compensated-dropped", "ensemble.py",
       "fs = run_kernels(self.cs, self.spec, t0, q0, v0, prep.prob.h, n_steps, every, self.compensated, self.tol)",
       "fs = run_kernels(self.cs, self.spec, t0, q0, v0, prep.prob.h, n_steps, every, True, self.tol)",
       "RunSpec(compensated=False) runs compensated sums in the kernel tasks", "paths",
       TENS + "::test_members_run_with_the_summation_asked_for", TENS),
    _m("paths-broken-pool-not-renewed", "executors.py",
       "            return place.local_pool\n", "            return False\n",
       "a local pool broken by a dead worker is not replaced: its retried units fail again", "paths",
       TDASK + "::test_a_worker_killed_mid_run_loses_nothing_on_the_local_pool", TDASK),
    # --- the guard -----------------------------------------------------------------------------
    _m("paths-guard-window-ignored", "core/guard.py",
       "bad = [n for n in cand if a[n] > SAFETY * a[max(0, n - WINDOW):n].max() + floor[n]]",
       "bad = [int(n) for n in cand]",
       "the guard compares a step's energy change with its predecessor's only, not the window's largest",
       "paths", TG + "::test_threshold_is_relative_to_the_previous_steps", TG),
    _m("paths-guard-iterations-min", "core/guard.py",
       "iterations > ITER_FACTOR * max(self.its) + ITER_EXTRA", "iterations > ITER_FACTOR * min(self.its) + ITER_EXTRA",
       "the guard's iteration test against the window's smallest count (flags ordinary steps)", "paths",
       TGE + "::test_the_iteration_test_is_against_the_window_s_largest_count", TGE),
    _m("paths-guard-root-agree-ignores-tol", "core/guard.py",
       "agree = ROOT_AGREE if tol is None else max(ROOT_AGREE, ROOT_TOL_FACTOR * float(tol))",
       "agree = ROOT_AGREE",
       "two roots compared at round-off whatever the user's Newton tolerance: tol = 1e-5 ends the "
       "friction skate with a false 'two roots'", "paths",
       TG + "::test_a_loose_newton_tolerance_is_not_a_second_root", TG),
    _m("paths-guard-head-unjudged", "core/guard.py",
       "head = 1 < every <= HEAD", "head = False",
       "with save_every > 1 the first saved interval is never judged", "paths",
       TG + "::test_a_second_root_between_saved_samples_is_located", TG),
    _m("paths-guard-rerun-length-without-t0", "core/guard.py",
       "last = steps_between(samples.t[0], samples.t[min(j, len(t) - 1)], h)",
       "last = steps_between(0, samples.t[min(j, len(t) - 1)], h)",
       "the guard's rerun length counted from t = 0, not t0 (t0 < 0: a negative length; large t0: "
       "the flagged interval left unverified)", "paths",
       TG + "::test_a_second_root_between_saved_samples_is_located_from_any_t0", TG),
    # --- the kernel specialised per (s, n, m) ----------------------------------------------------
    _m("paths-specialised-sizes-swapped", "compiled/specialised.py",
       'r"\\1s, m, n = S_, M_, N_"', 'r"\\1s, m, n = S_, N_, M_"',
       "the specialised kernel's frozen constraint geometry sized (s, n, m) where the generic one reads "
       "(s, m, n): other numbers than the generic kernel's", "paths",
       TSP + "::test_the_specialised_kernel_returns_the_generic_kernels_bits", TSP),
    _m("paths-specialised-not-reported", "compiled/quasi.py",
       'newton_kind="quasi", kernel_specialised=special)', 'newton_kind="quasi", kernel_specialised=False)',
       "Result.stats says the generic kernel ran when the specialised one did", "paths",
       TSP + "::test_integrate_runs_it_when_ready_and_says_so", TSP),
    _m("paths-specialised-switch-ignored", "compiled/specialised.py",
       '    if not enabled():\n        return None\n    ep = _ready.get(key)',
       '    ep = _ready.get(key)',
       "LDASPARK_SPECIALISE=0 ignored where a specialised kernel is ready", "paths",
       TSP + "::test_integrate_runs_it_when_ready_and_says_so", TSP),
    _m("paths-specialised-build-at-once", "compiled/specialised.py",
       "if (_spent[key] < BUILD_AFTER or key in _failed", "if (key in _failed",
       "the build process started at the first look into the cache, not after BUILD_AFTER seconds "
       "(every run of a new size pays a 30 s compile on one core)", "paths",
       TSP + "::test_a_build_is_started_once_after_build_after_and_its_result_loaded", TSP),
    # --- the lab's tools -----------------------------------------------------------------------
    _m("paths-fingerprint-paths-py-only", "lab/checkpoint.py",
       "        _hash_tree(h, root, \"*\")", "        _hash_tree(h, root, \"*.py\")",
       "the checkpoint fingerprint covers only the *.py files under its paths (data files edited: "
       "a stale record resumed)", "paths",
       TCKR + "::test_every_copied_file_is_in_the_fingerprint", TCKR),
    _m("paths-fingerprint-package-py-only", "lab/checkpoint.py",
       "_hash_tree(h, pkg, \"*\")", "_hash_tree(h, pkg, \"*.py\")",
       "the checkpoint fingerprint covers only the package's *.py files (not the tableaux it reads)",
       "paths", TCK + "::test_the_fingerprint_hashes_the_whole_package_not_only_the_lab", TCK),
    _m("paths-file-error-counted-as-kill", "lab/mutants/mutation.py",
       "return node if \"::\" in node else None", "return node",
       "a collection error of a whole file ('ERROR tests/x.py') named as the failing test: a kill",
       "paths", TCLS + "::test_only_exit_1_with_a_failing_test_named_is_a_kill", TCLS),
    _m("paths-peer-ratio-inverted", "lab/reports/summary.py",
       "{r['odelab_cpu'] / r['generic_cpu']:.1f}x", "{r['generic_cpu'] / r['odelab_cpu']:.1f}x",
       "the README's odelab / generic CPU ratio printed upside down", "paths",
       TRM + "::test_readme_numbers_and_verdicts_come_from_the_reports", TRM),
    _m("paths-dps-ratio-inverted", "lab/reports/summary.py",
       "r['seconds_per_step'] / base[0]['seconds_per_step']", "base[0]['seconds_per_step'] / r['seconds_per_step']",
       "the README's cost per step at dps digits over float64 printed upside down", "paths",
       TRM + "::test_readme_numbers_and_verdicts_come_from_the_reports", TRM),
)
