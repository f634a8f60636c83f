"""The solver's thresholds and tuning constants, in one place.

Each is a number the solver compares against or iterates up to; the
modules that use it import it from here (their module attribute of the
same name is this value). Constants of older modules (the BDF's and
Newton's controls, the model checks' limits) still live in their modules:
issue 38 moves them here as the step loop is compiled, where they reach
the compiled code as arguments.
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
#: Newton iterations of one trial pressure's solve for the other unknowns,
#: and the relative update (besides Newton's atol) it stops at
INNER_ITERATIONS = 30
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


# -- The compiled step loop (softflow.solve.steploop) ------------------------------------------
#: Whether the adaptive BDF takes its usual steps in the compiled loop
#: (:func:`softflow.laws.stepper.stretch`) where it serves the run; False
#: takes every step in Python (the benchmarks compare both).
COMPILED_STEPS = True
#: Accepted steps the compiled loop records before it hands them to the
#: run's recorder (and reports progress); each call allocates nothing.
COMPILED_RECORD_ROWS = 256
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
