"""The main demo: WhiskerRatSLAM maps one object for two loops: a thin script over :mod:`cansim.studies.whisker_ratslam_demo` (same as ``cansim demo``; ``--help`` lists the options)."""
from cansim.studies.whisker_ratslam_demo import main

if __name__ == "__main__":
    from whisker_io.command_line import run_command

    raise SystemExit(run_command(main, "whisker_ratslam_object"))
