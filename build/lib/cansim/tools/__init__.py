"""Tools around the models: the ``cansim`` command line (:mod:`~cansim.tools.cli`),
parameter sweeps on Dask (:mod:`~cansim.tools.sweep`), ROS bag replay without ROS
(:mod:`~cansim.tools.bag_replay`) and the benchmark suite (:mod:`~cansim.tools.benchmark`).
The last stage of the data flow: tools may import anything, nothing imports them.
"""
