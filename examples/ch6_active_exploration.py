"""Thesis Ch.6 study (active exploration for fast recognition): a thin script over :mod:`cansim.studies.ch6_active_exploration` (same as ``cansim study ch6``; ``--help`` lists the options)."""
from cansim.studies.ch6_active_exploration import main

if __name__ == "__main__":
    from whisker_io.command_line import run_command

    raise SystemExit(run_command(main, "ch6_active_exploration"))
