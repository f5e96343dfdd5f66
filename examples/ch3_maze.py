"""Thesis Ch.3 study (whisker RatSLAM in the maze): a thin script over :mod:`cansim.studies.ch3_maze` (same as ``cansim study ch3``; ``--help`` lists the options)."""
from cansim.studies.ch3_maze import main

if __name__ == "__main__":
    from whisker_io.command_line import run_command

    raise SystemExit(run_command(main, "ch3_maze"))
