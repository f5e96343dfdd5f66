"""The main demo: WhiskerRatSLAM maps one object for two loops: a thin script over :mod:`cansim.studies.whisker_ratslam_demo` (same as ``cansim demo``; ``--help`` lists the options)."""
from cansim.studies.whisker_ratslam_demo import main

if __name__ == "__main__":
    raise SystemExit(main())
