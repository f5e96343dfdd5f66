"""RatSLAM (3-DoF) on a synthetic 5-loop route: a thin script over :mod:`cansim.studies.ratslam_demo` (same as ``cansim demo ratslam``; ``--help`` lists the options)."""
from cansim.studies.ratslam_demo import main

if __name__ == "__main__":
    from whisker_io.command_line import run_command

    raise SystemExit(run_command(main, "ratslam_synthetic"))
