"""The thesis studies and the demos, as importable modules (``cansim study``, ``cansim demo``).

Each study module has ``main(argv)`` (its command line, ``--quick`` for the quick mode
that shows the headline result) and the functions it is built from, so a study runs
from an installed wheel with no checkout; the scripts in ``examples/`` only call
``main``. Ch.3: :mod:`~cansim.studies.ch3_maze`; Ch.4:
:mod:`~cansim.studies.ch4_radial_distance`; Ch.5: :mod:`~cansim.studies.ch5_object_maps`;
Ch.6: :mod:`~cansim.studies.ch6_active_exploration`; demos:
:mod:`~cansim.studies.whisker_ratslam_demo` (the main demo) and
:mod:`~cansim.studies.ratslam_demo`.
"""
