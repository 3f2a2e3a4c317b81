"""Stage 4, the run: the Python side of the time loop over `kernel/` (`simulation`: settings, chunks,
checks, summary; `stepper`: step by step), one validation of settings (`settings_check`), the size of
a run's outputs (`output_size`) and their default names (`output_names`), the one-time kernel
compilation (`first_compile`), child processes that end with their parent (`children`) and the
until-settled study (`study`)."""
