"""The solver's thresholds and tuning constants, in one place.

Each is a number the solver compares against or iterates up to (or a switch
of its tuning); the modules that use it import it from here by name (their
module attribute of the same name is this value, and is what they read: to
change one for a test, patch that module's attribute, ``bdf.SAFETY``; the
compiled step loop's own are read here, ``settings.COMPILED_STEPS``). The
compiled step loop takes the BDF's, Newton's and the linear algebra's from
those modules' attributes at each run (softflow.solve.steploop), as arguments.

Issue 38 moved the BDF's and Newton's controls and the linear algebra's,
assembly's and the model checks' limits here. What stays in its module: the
compiled stepper's slot indices (IST_SIZE, FST_SIZE and the indices into
them, softflow.laws.stepper) and the laws' kind codes, which tune nothing;
values derived from these (the BDF's coefficients bdf._G, _ERR, _PRED_PSI;
model_checks.NEAR_MACH, validity.NEAR_FRACTION x MACH_INCOMPRESSIBLE); and
the constants of modules not yet moved: Simulation's defaults (MAX_STEPS,
NEWTON_RTOL, NEWTON_FRACTION), the integrator's (RESCUES_IN_A_ROW,
INITIAL_CONFIRMS), the batched engine's (batched), the sensitivities', and
those of condense, progress and validity.
"""

# -- A run's times ---------------------------------------------------------------------------
#: Relative round-off allowed where a time must lie within the run: a fixed step
#: up to duration·(1 + ROUND_OFF) (duration=0.3 with step=3*0.1, 0.30000000000000004),
#: breakpoints from -ROUND_OFF·duration to duration·(1 + ROUND_OFF). The fixed-step
#: grid allows the same (ImplicitEuler: ceil(duration / step - 1e-9) steps).
ROUND_OFF = 1e-9

# -- Checks of the inputs at the start of a run ----------------------------------------------
#: A tube's flow is negligible (check ``'tube_negligible_flow'``, a ModelWarning
#: at the start of the run) where, over the whole run, it could equalize at most
#: NEGLIGIBLE_TUBE · rtol of the pressure difference across it in the smallest
#: volume it reaches: its time constant with that volume exceeds the duration
#: by more than 1 / (NEGLIGIBLE_TUBE · rtol), 1e9 at the default rtol. Six
#: orders of magnitude below the run's own tolerance: a slow leak that a run
#: resolves is no finding; a 1 nm x 1 km tube into a 10 mL tank of air (tau =
#: 7e25 s) or a 0.3 m tube whose diameter was given in m for mm (1 um: 2e10 s)
#: is, over a 1 s run.
NEGLIGIBLE_TUBE = 1e-6

# -- The consistent start at nodes without volume (softflow.solve.sourcenodes) ---------------
#: [Pa] the highest absolute pressure a consistent start may put at a node
#: without volume that a flow source feeds: a balance that needs more (a
#: source pushing against a closed valve, an inertial tube at rest, a
#: choked nozzle) is refused, not reported as a kilobar answer
PRESSURE_CAP = 1e9
#: [Pa] the lowest absolute pressure the search goes down to, for a source
#: that draws from such a node
PRESSURE_FLOOR = 1.0
#: the factor between the pressures the bracketing search tries
MARCH = 2.0
#: the most pressures the bracketing search tries (from 1 atm to the cap
#: or the floor: 14 or 17; more near the edge of a fluid's range)
MARCH_TRIALS = 200
#: where a region's node at the edge of its fluid's pressure range cannot be
#: solved for (another node of the region lies past it), the diagnosis of
#: :func:`softflow.solve.sourcenodes._reach` tries these fractions of the
#: edge's pressure inside it, nearest first, before marching from the start
#: (a pump into two water nodes behind a check valve, refused at t = 0: the
#: march and its narrowing towards the edge took 125 residual evaluations)
EDGE_BACKOFF = (1e-3, 1e-2, 0.1)
#: Newton iterations of one trial pressure's solve for the other unknowns,
#: and the relative update (besides Newton's atol) it stops at
INNER_ITERATIONS = 30
#: ... of a trial started with the region's other node pressures shifted
#: along (2-3 where it serves); one that has not converged by then is solved
#: again from where they were (its 30 iterations were most of a refused
#: start's work: an air region at the table's 10 kPa edge, 33 evaluations a
#: trial where the second start took 3)
INNER_SHIFTED = 8
INNER_RTOL = 1e-9
#: iterations of the bracketed search for the balancing pressure, and the
#: relative width it stops at (a start: the network's Newton finishes it)
SEARCH_ITERATIONS = 80
SEARCH_RTOL = 1e-10
#: the most nodes a region of nodes without volume grows to
#: (:func:`local_nodes` with ``region``)
REGION_NODES = 64

# -- Failures and their culprits (softflow.solve.culprit) ------------------------------------
#: a mode whose time constant lies below this fraction of the smallest step
#: tried is named beside a failure (:func:`fastest_mode`)
FAR_BELOW = 1e-3
#: a step's failed solve that repeats STALL_REPEATS times on ever shorter
#: steps, its refused unknowns within STALL_RTOL (plus Newton's atol), stops
#: the run (:meth:`Finder.stalled`)
STALL_REPEATS, STALL_RTOL = 4, 1e-3
#: a flow source's node that balances at the last accepted point but not at
#: that point moved on by its rates to the failed step's end stops the run
#: where the node's balance at its limit (1 Pa, 1 GPa or its fluid's edge)
#: changes sign within this fraction of the step, linear in time: the
#: supply runs out there (a pump drawing through a tube choked from a
#: container that empties; no step gets past it, and the steps crawled
#: towards it in slivers: 543 residual evaluations after the last step)
#: (:meth:`softflow.solve.culprit.Finder.unbalanced`)
EXHAUSTED_WITHIN = 0.01
#: ... or within this fraction of the point's time (the result then ends that
#: close to where the supply runs out): at a tight rtol (1e-6) the BDF's
#: steps near it, 1e-10 s at t = 0.039 s, failed as the node's pressure fell
#: steeply to its limit, each ending nearer it and the sign change at 60-97 %
#: of the next, until the smallest step's continuation (~1 000 residual
#: evaluations after the last step)
EXHAUSTED_RESOLVED = 1e-8
#: a run stopped at max_steps names its fastest mode where that mode's time
#: constant lies below this many times the last step (the steps follow it)
STEP_FOLLOWS = 100.0
#: a mode names the components whose states move in it by at least this
#: share of the most moved (relative to their values), MODE_NAMES at most
MODE_SHARE, MODE_NAMES = 1e-3, 3
#: the largest network (unknowns) whose modes are computed densely on a
#: failure (an eigenvalue problem of n x n: ~0.1 s at 600)
MODES_MAX_UNKNOWNS = 600

# -- Volumes that empty (softflow.solve.integrator.VolumeWatch) ------------------------------
#: A watched volume's state (:class:`VolumeWatch`) counts as past its limit
#: where it ends a step below it by more than this many times its absolute
#: tolerance (the BDF's atol of the state; 1e-12 kg at fixed steps), or by
#: more than EMPTY_SLACK_SHARE of its initial distance from the limit where
#: that is smaller (a 1e-15 m^3 container of gas holds ~1e-15 kg): within that,
#: the state is at its limit as far as the run resolves it.
EMPTY_SLACK_ATOL, EMPTY_SLACK_SHARE = 10.0, 1e-3
#: absolute tolerance of a stored mass at fixed steps (Simulation's default)
EMPTY_ATOL_FIXED = 1e-12
#: a step retried to locate where a volume empties ends this fraction of the
#: located crossing short of it; EMPTY_TRIES such placements, then quarters
EMPTY_PAST, EMPTY_TRIES = 1e-3, 4
#: the step after one that ended just short of a located crossing ends this
#: many times its distance to the crossing (linear estimate) past its start:
#: past the crossing, where the run stops, in a step whose solve is short
#: (the grid's next step from there failed Newton twice in the random
#: networks, 80-170 residual evaluations before the stop)
EMPTY_AHEAD = 4.0

# -- Recorded points (softflow.solve.simulation) ----------------------------------------
#: Largest ``refine=`` (points recorded per adaptive step).
MAX_REFINE = 64

# -- Dense output (softflow.solve.dense, refine='auto') --------------------------------------
#: Points per step ``refine='auto'`` records at most.
AUTO_REFINE_MAX = 64
#: ``refine='auto'``: a step gets r points where the straight lines between
#: them stay within AUTO_REFINE_TARGET of its polynomial, in units of the
#: run's tolerance (atol + rtol x the run's largest magnitude of each state,
#: and of each unknown's quantity, as the error test weighs the unknowns).
AUTO_REFINE_TARGET = 1.0

# -- The BDF's step control (softflow.solve.bdf) ---------------------------------------------
#: The highest order of the adaptive BDF (Simulation's default ``max_order``).
MAX_ORDER = 5
#: The step controller's safety factor on the step its error estimate allows.
SAFETY = 0.9
#: Newton's tolerances are at least NEWTON_FLOOR (relative to the run's
#: largest magnitude of each quantity; ``Newton.scale_floor``) where that is
#: below Newton's rtol times NEWTON_FLOOR_FRACTION: a settled network's
#: vanishing flows are not asked for what round-off cannot resolve, while a
#: decaying flow that still moves mass is resolved to its own size. Measured:
#: the air chain of bench_accuracy (flows falling 1000x from the jump) at
#: rtol 1e-2 took 57 steps with the floor at Newton's rtol (36 with it at
#: 1e-6) and 351 at rtol 1e-7 (191 with it at a fifth of Newton's rtol);
#: bench_speed_accuracy's 12 -> 18 MPa scene, settled at rtol 1e-8, stops
#: without a floor.
NEWTON_FLOOR, NEWTON_FLOOR_FRACTION = 1e-6, 0.2
#: The least and the most factor by which a step changes from one to the next
#: (a rejected step's cut: at least MIN_FACTOR).
MIN_FACTOR, MAX_FACTOR = 0.2, 2.0
#: a step is only lengthened by at least this factor (each change costs a
#: re-interpolation and, past Newton's reuse window, a factorization)
GROW_MIN = 1.2
#: a step that switches a mode is placed to end at most this fraction past the
#: crossing of its switching function (less where the step moves by more than
#: the tolerance); SECANT_TRIES placements, then bisection
SWITCH_PAST = 1e-3
SECANT_TRIES = 4
#: accepted steps for which a step stays below 0.9 x the last one that failed
#: the error test (or below the bisected step while a mode switch is located)
FAIL_HOLD = 10
#: a run stops where this many accepted steps in a row each switched a mode at
#: a step of at most CHATTER_STEP x step_min: a mode that undoes itself as soon
#: as it is taken (a flow source pushing into a snapping valve with no volume
#: between them: ~20 step tries a switch, 10 million steps, the default limit,
#: in ~25 minutes before)
CHATTER_SWITCHES = 50
CHATTER_STEP = 4.0
#: a step taken past the error test at step_min (forced) restarts the method
#: at order 1 from its point, unless no step has passed the test since the
#: last restart (bdf.BDF._take): where Newton took an actuator's gas to another
#: volume holding its mass (past a fold, in a step of its own rather than by
#: a fold jump), the history before extrapolated a trajectory that no longer
#: is, and the next steps bounced between the two volumes until the run
#: stopped. The latex balloon's curve with 1 kPa of noise (many folds), a
#: pump filling and drawing it for 38 s, 12 noise seeds: 7 runs went
#: through before, 12 now (with newton.CRDOWN, 3 without this restart); the
#: paper listing (an undeclared jump at 0.5 s) 106 -> 43 steps at the same
#: error; nine paper scenes: no forced step at the default rtol, unchanged.
#: Where the probes of a restart that only a forced step asked for fail (a
#: marginal failure of the error test rather than a jump), BDF goes on with
#: its history (bdf.BDF._propose)
FORCED_RESTART = True
#: the first step after a (re)start aims at this error estimate (order 1, in
#: units of the tolerance): its order-1 steps carry the run's largest local
#: errors until the order rises. Measured: the paper listing at the default
#: rtol 0.110 % of its gauge peak from a converged run aiming at 1/4 (the
#: first two steps 0.02 s each), 0.047 % at 1/10 (104 steps against 99)
FIRST_ESTIMATE = 0.1
#: Newton's damped full stage (a fresh Jacobian at every iterate, a line
#: search) and, in thermal scenes, its flows-first stage are tried only on
#: steps of at most this many step_min; on a longer step whose chord
#: iterations fail on fresh factors the step is rejected and cut by 4 at
#: once, as IDA does (a shorter step is the cheaper cure: its predictor is
#: closer). Measured on the nine paper scenes at the default rtol:
#: factorizations 1 445 -> 1 123, residual evaluations 7 556 -> 5 988, steps
#: 2 089 -> 2 243; Fig. 5 with air 481 -> 257 factorizations (its snaps: a
#: failing full stage cost ~12 factorizations each); Fig. 3's three scenes
#: with air, adiabatic: factorizations 1 331 -> 542, residual evaluations
#: 6 679 -> 2 333, steps 726 -> 723.
FULL_STAGE_STEPS = 4.0
#: on longer steps, chord iterations on fresh factors that contract too slowly
#: go on as undamped full Newton before the step is cut
#: (:attr:`softflow.solve.newton.Newton.undamped_full`). Measured: the
#: 12 -> 18 MPa bottle of benchmarks/assess_scenes (heat transfer, table air,
#: rtol 1e-3) 31 -> 14 steps, where its turbulent tube's flow dies out; the
#: nine paper scenes 2 243 -> 2 143 steps, 5 916 -> 6 003 Newton iterations,
#: 1 129 -> 1 162 factorizations (Fig. 5 with air 447 -> 403 steps, 257 -> 289
#: factorizations; in runs in turns 3-6 % slower, Fig. 3's hysteretic scene
#: 5-15 % faster).
UNDAMPED_FULL = True
#: The BDF's error norm is the weighted RMS over the error test's entries, or the
#: largest weighted entry over PEAK_FACTOR where that is larger: by RMS alone one
#: entry of n may carry sqrt(n) times the tolerance, and a large network's
#: error then grows with its size (air chain N = 200, rtol 1e-8: 23x rtol by
#: RMS, 5x with the peak held to 3x).
PEAK_FACTOR = 3.0

# -- Newton (softflow.solve.newton) -------------------------------------------------------
#: full Newton steps the watchdog may take without residual decrease
WATCHDOG = 6
#: the damped stage (:meth:`softflow.solve.newton.Newton._full`) keeps its
#: factors for the next iteration only where a full step cut the scaled
#: residual by 1/FULL_KEEP_CUT or more (Shamanskii's variant: close to the
#: solution Newton's quadratic convergence passes it, and a factorization is
#: saved), and by 1/TIGHT_KEEP_CUT in a solve held to TIGHT_RTOL or less (BDF's
#: restart probes, at 1e-12): many decades below the residual the stage starts
#: from, a chord step that contracts only linearly costs more iterations than a
#: refactorization. Measured: past each opening of Fig. 4's snapping valve
#: (dp ~ mdot^2) the probes' chord steps contracted by ~10x each, 8 iterations from
#: a residual of 53 to the tolerance; with 100x there, the damped iterations
#: 139 -> 95 over the run. Not at the run's own tolerances: the consistent
#: start of a check valve whose root sits in its narrow opening band
#: (tests/fons, thresholds 10 and 30 kPa) then took another path through the
#: band and failed
FULL_KEEP_CUT, TIGHT_KEEP_CUT, TIGHT_RTOL = 0.1, 0.01, 1e-10
#: the damped stage's line search halves its step length down to LINE_SEARCH_MIN
#: (then the watchdog's undamped steps, or the solve fails); where a trial's
#: scaled residual is more than LINE_SEARCH_GROSS times the starting one
#: (a gross overshoot: a tube so short that its zero-flow slope, its laminar
#: friction alone, is ~1e-13 of the law's slope at the flow it carries, sends a
#: first Newton step from rest 3e10 times past that flow) the next length comes
#: from the residual's growth between the last two trials, as a power law, and
#: may go down to LINE_SEARCH_DEEP (:func:`softflow.laws.stepper.backtrack`,
#: both Newtons), at the consistent start only. Measured: a 1 nm x 1 cm air
#: tube from a 1.5 bar source into a tank, refused at t = 0 after 289
#: residual evaluations with halving alone, runs (the law's entry-limited
#: flow, 0.0243 kg/s, to 1e-6); within a run, a pump drawing through a tube
#: at its choked flow (adaptive, rtol 1e-6), whose continuation at the
#: smallest step fails anyway, took 9 504 residual evaluations after its last
#: step with it, 1 012 without
LINE_SEARCH_MIN, LINE_SEARCH_GROSS, LINE_SEARCH_DEEP = 1e-4, 1e6, 1e-15
#: the damped stage fails at once where this many iterations in a row aim
#: their full step past the same edge of a fluid's range (the same quantity
#: and limit): the root lies past it, and the line search's trials only
#: close in on the edge (a pressure source held at 41 kPa below table
#: water's 50 kPa: 67 residual evaluations in the stage, ~20 with 3)
RANGE_AIMS = 3
#: :meth:`softflow.solve.newton.Newton.continuation`: its first step in lam,
#: the smallest, and the most Newton solves it makes (a bound on the cost of a
#: run that fails anyway: the tests/fons 2 bar pulse through a check valve,
#: cracking 0-92.5 kPa, took up to 27, 16 in the median); and the Newton rtol
#: it holds its solves to at most (at a run's rtol 1e-2, Newton at rtol/20
#: accepted a first update on its predicted contraction short of a check
#: valve's opening band, and the continuation stalled there: the fons ideal
#: valve at 72.5 kPa)
CONTINUATION_FIRST, CONTINUATION_MIN, CONTINUATION_SOLVES = 0.125, 1e-4, 64
CONTINUATION_RTOL = 1e-6
#: The convergence test of a chord iteration takes the contraction rate as at
#: least CRDOWN times the rate it took at the iteration before, 1 on fresh
#: factors (CVODE's damped rate, crate; SUNDIALS' CRDOWN = 0.3): a rate
#: measured from the first pair of updates alone sees the predictor's jump
#: (a source's step: 1e6 tolerances, then 805), not the slow mode left where
#: the predictor's Jacobian is far from the root's (an orifice's slope at
#: rest: chord rate 0.92 from there on), and the second iterate was accepted
#: 2.5e4 tolerances from the root (tests/test_random_networks.py drawn with
#: Python's random, seeds 1000-1599, each at fixed steps and adaptive:
#: accepted points > 100 tolerances 61 -> 4 and 35 -> 5, statuses unchanged,
#: Newton iterations +2.9 / +3.3 %; nine paper scenes: Newton iterations 6012 ->
#: 6211, factorizations 1171 -> 1160). The rate the next solve's first update
#: is judged on (``eta``) stays the measured one
CRDOWN = 0.3
#: A chord update within FLIP_MATCH of the reverse of the update before
#: (|step + previous| <= FLIP_MATCH |step| in the update norm), at a rate of
#: 0.9 to 1/0.9, is an iteration flipping about a root where the law's slope
#: is far steeper than the Jacobian's, or shallower (a square root: an
#: orifice's flow at a dead end, dp +-2 Pa about the tank's pressure, outside
#: the law's 0.03 Pa linear band; the chord on f = sqrt|x| goes x -> -x
#: forever): half of it is taken, once a solve, instead of calling the
#: iteration diverging. Measured: a 0.1 L container at 1.5 bar with a Cd
#: orifice into a dead end took 16 144 steps (then max_steps = 20 000) by t =
#: 0.106 ms, each ~6 ns; since, it runs its 0.1 s in ~30 steps
FLIP_MATCH = 0.1
#: Up to this many unknowns Newton's tolerance scale, update norm and
#: pressure test reduce on Python lists: ``a.tolist()`` and the builtins max/min
#: take 0.2-0.3 us for 6 entries where a NumPy reduction takes 0.8 us (its
#: fixed cost, measured on NumPy 2.4); the list's cost grows ~25 ns per entry.
SMALL = 32

# -- Linear algebra (softflow.solve.linalg) -------------------------------------------------
#: Up to this many unknowns a dense LU is at least as fast as SuperLU: measured
#: on chains (benchmarks/bench_linear_solver.py), dense wins 1.03-1.2x up to 130
#: unknowns and loses 2x at 146 (the n^3 factorization takes over).
DENSE_MAX = 128
#: SuperLU's relaxed-supernode size. Its default (a few columns) merges small
#: near-dense column groups into supernodes whose triangular solves go through a
#: BLAS call each; on the 2x2 (pressure, temperature) blocks of thermal networks
#: that made each solve ~2x slower (bench_thermal.py chain N=1000: 0.38 -> 0.17 ms
#: per solve), and factoring is ~1.3x faster with 1 on both kinds of network.
RELAX = 1
#: Largest array for the dot-product shortcuts (linalg.all_finite). OpenBLAS
#: runs larger dot products on several threads, and on a loaded 2-core
#: machine their hand-offs were measured to cost milliseconds each (chain
#: N = 10 000: 3x slower runs).
DOT_MAX = 1000
#: Up to this many unknowns linalg.DenseLU solves by a product with the inverse
#: instead of LAPACK getrs (measured: 0.28 vs 0.44 us on 6 unknowns, 0.36 vs
#: 1.0 on 36, 0.49 vs 1.6 on 64). Newton only needs the update to a relative
#: accuracy far coarser than the inverse's round-off, and checks convergence on it.
INVERSE_MAX = 64
#: A dense LU whose smallest pivot is at most this times its largest is singular.
PIVOT_RTOL = 1e-14
#: Up to this many unknowns the pivots' extremes are taken on a Python list
#: (DenseLU)
SMALL_PIVOTS = 32


# -- The compiled step loop (softflow.solve.steploop) ------------------------------------------
#: Whether the adaptive BDF takes its usual steps in the compiled loop
#: (:func:`softflow.laws.stepper.stretch`) where it serves the run; False
#: takes every step in Python (the benchmarks compare both).
COMPILED_STEPS = True
#: Whether the consistent start's solve from the initial values is made in
#: one compiled call (:func:`softflow.laws.stepper.start_solve`) where that
#: serves the run (:func:`softflow.solve.steploop.start_solver`; the Python
#: solve where it does not converge); False: always the Python solve.
COMPILED_START = True
#: Whether a batched sweep's variants run each on its own clock in the
#: compiled loop (:mod:`softflow.solve.variants`) where that serves the
#: scene; False: the shared step sequence (:mod:`softflow.solve.batched`).
COMPILED_VARIANTS = True
#: Whether the compiled network loop evaluates a user's component (the paper's
#: Actuator) by calling it back in Python (softflow.solve.usercall), so that
#: its scenes run in the compiled loop; False: such a network keeps the
#: per-group path (and the Python step loop).
COMPILED_USER = True
#: Whether a user's component whose functions numba can compile as written
#: (the paper's Actuator) is compiled, with its finite-difference Jacobian,
#: and called natively by the compiled loop (softflow.solve.usercompile:
#: compiled once, cached under numba's cache directory); False, or where
#: numba cannot compile them: called back in Python (COMPILED_USER)
COMPILED_USER_CODE = True
#: Whether the floats, fluids and PV curves that a compiled user component's
#: ``evaluate`` / ``update_state`` read from their closures (or attributes, or
#: module globals) are run-time data
#: of one kernel (read from the component's layout at each call: a design
#: loop over a stiffness or a curve compiles once) rather than constants
#: compiled in (a kernel per set of values). Off: constants, as before
USER_RUNTIME_VALUES = True
#: How many kernels a process compiles for one user function's code, each
#: for other values read from its closure or globals that are compiled in
#: as constants (a global, an int, a tuple, an array, a helper function's
#: closure: a design loop that changes one would compile at every run);
#: past this, the function is called back (said once, INFO). Kernels found
#: in the cache do not count
USER_COMPILES_MAX = 4
#: The most variables times rows (or states) of a user component whose
#: compiled kernel (softflow.solve.usercompile) is unrolled, each entry a
#: name of its own; a larger component is called back
USER_UNROLL_MAX = 256
#: How deep a user's functions that call the user's other functions are
#: compiled with them (deeper, or recursive: called back)
USER_CALL_DEPTH = 4
#: Compiled user components (their modules under numba's cache directory,
#: softflow.solve.usercompile) not loaded for this many days are deleted, with
#: numba's cache of them, when a process first compiles one (each new set of
#: constants and each softflow version adds a module)
USER_CACHE_DAYS = 30
#: A compile of a user's component longer than this [s] is said once (an
#: INFO line on the 'softflow' logger); loading it from the cache is not
COMPILE_NOTICE = 0.5
#: Views a call-back keeps of the loop's arrays, by their addresses and sizes
#: (softflow.solve.usercall: the loop passes the same few arrays at every
#: call); past this many (arrays of earlier runs) they are dropped
CALLBACK_VIEWS_MAX = 64
#: The last errors of Python signals called back that usercall.RAISED keeps
#: (for inspection: the Python path raises each again itself)
CALLBACK_ERRORS_KEPT = 8
#: A `softflow demo` run longer than this [s] compiled the step loop first
#: (the run itself takes milliseconds): it is run again and both are reported
DEMO_COMPILED_RUN = 1.0
#: Batched variants in the compiled loop (softflow.solve.variants): the
#: fewest split over two threads (fewer run in one), the variants a thread
#: runs per call of the loop (between two looks of the progress bar), and
#: the record rows first allocated per variant (more are given where a run
#: needs them: the variants that did not fit are run again)
VARIANT_THREADS_MIN = 16
VARIANT_CHUNK = 64
VARIANT_ROWS = 64
#: Accepted steps the compiled loop records before it hands them to the
#: run's recorder (its progress reports do not wait for that); each call
#: allocates nothing. As many as COMPILED_RECORD_BYTES hold (the step's
#: point, integrals and dense-output differences), at least
#: COMPILED_RECORD_ROWS and at most COMPILED_RECORD_ROWS_MAX
#: (softflow.solve.steploop.record_rows): fig5:air's 385 steps took three
#: calls of the loop (its 256-row buffers full once) and take two now.
COMPILED_RECORD_ROWS = 256
COMPILED_RECORD_ROWS_MAX = 1024
COMPILED_RECORD_BYTES = 2_000_000
#: Where the run's records must grow, they grow to the points (and dense
#: output rows) expected in all at the pace so far, times EXPECT_MARGIN,
#: where that is less than doubling, and by EXPECT_GROWTH_MIN at least (a
#: pace that quickens is not met by a copy at every hand-over): a 2 000-
#: component water network records ~350 MB of points, and each doubling
#: copied them into fresh memory (:func:`softflow.solve.dense.grown_rows`)
EXPECT_MARGIN, EXPECT_GROWTH_MIN = 1.1, 1.25
#: Whether a run's arrays may ask Linux for transparent huge pages (NumPy's
#: ``madvise(MADV_HUGEPAGE)`` on arrays of 4 MB and more, its default). False:
#: NumPy's switch is off while a run integrates and assembles its result
#: (:class:`softflow.solve.simulation._huge_pages_off`), and restored after:
#: where the kernel compacts memory to find a huge page at the first touch
#: (transparent_hugepage/defrag = madvise, a common default), the runs that
#: record hundreds of MB spent a fifth of their time there (the 2 000-
#: component water network of benchmarks/bench_water_network.py: 12.4 s CPU
#: with huge pages, 3.4 s of it system time, against 10.0 s without them).
HUGE_PAGES = False
#: Rejected steps and restarts the compiled loop keeps for the progress
#: reporter (its log) before it hands back (the loop hands back when full).
COMPILED_EVENT_ROWS = 256
#: The widest band (below or above the diagonal, in the order of
#: softflow.solve.steploop.band_layout) of a network too large for dense
#: factors that the compiled step loop still takes, with its banded LU
#: (chains and trees of components: a few unknowns).
COMPILED_BAND_MAX = 32
#: A network that dense factors serve is factored as a band by the compiled
#: loop (softflow.solve.steploop._banded) where the band is at most
#: 1/COMPILED_BAND_SHARE of the matrix's width (a chain of 31 tubes, 126
#: unknowns in a band 11 wide: 105 -> 36 us a step), and a band is asked for
#: only from COMPILED_BAND_MIN unknowns on (the ordering costs ~0.4 ms; a chain
#: of 8 tubes, 34 unknowns in a band 11 wide, stays dense).
COMPILED_BAND_SHARE = 4
COMPILED_BAND_MIN = 48
#: A network too large for dense factors is factored by the compiled loop's
#: sparse LU (softflow.laws.sparselu), faster than its banded LU even where
#: the band is narrow (chains: steploop._sparse); False: by the banded LU
#: where the band is within COMPILED_BAND_MAX, else the run takes the Python
#: loop, with its SuperLU or condensed factors.
COMPILED_SPARSE = True
#: The sparse LU refactors on its last row order while each pivot stays at
#: least this fraction of the largest entry below it in its column (KLU's
#: default pivot tolerance, 0.001), and searches a new order otherwise.
COMPILED_SPARSE_REFACTOR = 1e-3
#: Room for the sparse factors: this many times the entries of SuperLU's L
#: and U of the network's pattern (the loop's partial pivoting may fill
#: more; a factorization that does not fit hands the step to Python).
COMPILED_SPARSE_ROOM = 3

# -- Fixed costs of a run ------------------------------------------------------------------
#: Up to this many terminals in all, Assembly numbers the unknowns of library
#: groups on Python lists (assembly._number_small) instead of NumPy calls per
#: group (the same numbers); up to this many unknowns the model checks' per-network
#: work is done on Python lists too (model_checks.SMALL_NETWORK).
SMALL_NUMBERING_MAX = 256
SMALL_NETWORK = 256
#: The regularity tests' answers a process remembers by the exact bytes of the
#: pattern and the Jacobian (assembly._Answers; the oldest forgotten first).
REGULARITY_ANSWERS = 128

# -- Model checks (softflow.solve.model_checks) ----------------------------------------------
#: Mach number at the low-pressure end above which the mean-density tube law's
#: neglect of the gas's acceleration is no longer small (~5 % of the drop).
MACH_INCOMPRESSIBLE = 0.3
#: A volume's fill time below this fraction of its thermal time constant is
#: reported as not isothermal.
THERMAL_FRACTION = 0.1
#: Temperature difference [K] and heat-transfer shape assumed for the thermal
#: time constant of a volume that has no thermal model.
THERMAL_DT = 10.0
#: Pressures at which gas_compressibility asks CoolProp for Z (geometric, over the
#: pressures of the volumes it checks); Z - 1 between them is interpolated.
Z_GRID = 12
#: Before asking CoolProp, gas_compressibility reads Z - 1 on the same grid from
#: the gas's property table (built from the installed CoolProp version; its Z within
#: ~3e-8 of CoolProp's): where the largest |Z - 1| there plus this margin stays
#: short of a near miss, CoolProp could give no record either, and is not asked
#: (nor imported: 2-7 s on a first run). The margin is ~40x the tables' error bound.
Z_TABLE_MARGIN = 1e-6
#: An adiabatic gas volume's temperature that stays away from its wall's for
#: longer than this many thermal time constants is reported: by then a real
#: wall would have taken back most of the difference.
ADIABATIC_PERSISTENCE = 1.0

# -- Assembly's fast paths (softflow.solve.assembly) -----------------------------------------
#: Up to this many unknowns the regularity check factors a dense matrix
#: (a sixth of SuperLU's time on the paper's 6 unknowns, measured).
DENSE_CHECK_MAX = 64
#: Up to this many unknowns Assembly.subnetworks finds the connected parts by
#: union-find in Python (10-20 us) instead of scipy's sparse graph (~0.15 ms).
SMALL_BLOCKS_MAX = 256
#: Up to this many groups Assembly.residual runs as unrolled code
#: (Assembly._unrolled_residual).
UNROLL_MAX_GROUPS = 64
#: Up to this many unknowns Assembly's node rows are one dense matrix-vector
#: product.
NODE_DOT_MAX = 64
