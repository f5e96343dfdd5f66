"""Thesis Ch.5 study (6-D localisation and object identification): a thin script over :mod:`cansim.studies.ch5_object_maps` (same as ``cansim study ch5``; ``--help`` lists the options)."""
from cansim.studies.ch5_object_maps import main

if __name__ == "__main__":
    from whisker_io.command_line import run_command

    raise SystemExit(run_command(main, "ch5_study"))
