"""Thesis Ch.4 study (radial distance regression): a thin script over :mod:`cansim.studies.ch4_radial_distance` (same as ``cansim study ch4``; ``--help`` lists the options)."""
from cansim.studies.ch4_radial_distance import main

if __name__ == "__main__":
    from whisker_io.command_line import run_command

    raise SystemExit(run_command(main, "radial_distance_study"))
