"""The explorer's per-whisk odometry conversion: _odometry_of (typed errors) against the bare SpatialOdometry(*...)."""
import timeit, numpy as np
from _script_args import script_args
script_args(__doc__, "python bench/explorer_odometry_check.py (no arguments)")
from cansim.explore.explorer import _odometry_of
from maps.odometry import SpatialOdometry
from whisker_io.sim.odometry_noise import noisy_odometry
from whisker_io.sim.objects import make_object
from whisker_io.sim.trajectories import object_trajectory
from whisker_io.sim.whisk_chain import WhiskChain
a, b = object_trajectory(make_object("box"), "A", 1)[:2]
rng = np.random.default_rng(0)
odo = lambda p, q: noisy_odometry(p, q, rng)
for _ in range(2):  # alternately
    t_old = min(timeit.repeat(lambda: SpatialOdometry(*odo(a, b)), number=2000, repeat=5)) / 2000
    t_new = min(timeit.repeat(lambda: _odometry_of(odo, a, b), number=2000, repeat=5)) / 2000
    print(f"bare {t_old * 1e6:.1f} us, checked {t_new * 1e6:.1f} us, +{(t_new - t_old) * 1e6:.2f} us")
chain = WhiskChain(make_object("box"), contact_model="tip")
print(f"a simulated Box whisk {min(timeit.repeat(lambda: chain.features(a, rng), number=50, repeat=3)) / 50 * 1e3:.2f} ms")
