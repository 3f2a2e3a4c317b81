"""Stage 4, the run: the Python side of the time loop over `kernel/`: one run's data and its one driver
(`driver`), the checks it reads (`checks`), a run's own loads (`loads`), `simulation` (settings, chunks,
checks, summary; `stepper`: step by step), one validation of settings (`settings_check`), the size of
a run's outputs (`output_size`) and their default names (`output_names`), the one-time kernel
compilation (`first_compile`), child processes that end with their parent (`children`), the
until-settled study (`study`), the Lyapunov and Floquet exponents of a trajectory (`lyapunov`), and the
static equilibrium (`static`) and modes (`modes`) in the minimal coordinates of the constraint manifold
(`manifold`) from the compiled right-hand side at one state (`state_rhs`)."""
