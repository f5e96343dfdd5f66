"""The matchers of the recognition benchmark (cansim.studies.recognition): selection and the surface path.

Fast checks (the study's runs are in the slow ``test_recognition_study.py``): an unknown
matcher is refused before any work, and the surface matcher's per-whisk targets on a
hand-made two-object library go to the object whose stored surface the whisks touch.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim.errors import ConfigError
from cansim.studies import recognition
from maps.odometry import SpatialOdometry
from whisker_io.pose import Pose


@settings(max_examples=20, deadline=None)
@given(st.one_of(st.just(()), st.lists(st.sampled_from(["thesis", "surface", "Thesis", "", "region", "surface "]),
                                       min_size=1, max_size=3).filter(lambda m: any(x not in recognition.MATCHERS for x in m))))
def test_unknown_matchers_are_refused_before_any_work(tmp_path_factory, matchers) -> None:
    out = tmp_path_factory.mktemp("rec") / "out"
    with pytest.raises(ConfigError):
        recognition.run(out, objects=["mug"], novel=[], matchers=matchers, progress=False)
    assert not out.exists()


def _grid(z: float, n: int = 21, half: float = 0.15) -> np.ndarray:
    u = np.linspace(-half, half, n)
    x, y = np.meshgrid(u, u)
    return np.stack([x.ravel(), y.ravel(), np.full(x.size, z)], axis=1)


def test_surface_targets_go_to_the_touched_surface(tmp_path: Path) -> None:
    """Library: a plate at z = 0 and one at z = 0.09 m (9 cm apart, far beyond the residual's
    3-cm cap), loaded from the study's surface files. The arm sits 0.2 m above the origin looking down (-z)
    and feels 5 points of the z = 0 plate per whisk, not moving: every impulse is object 0's."""
    files = []
    for k, z in enumerate((0.0, 0.09)):
        files.append(tmp_path / f"s{k}.npz")
        np.savez_compressed(files[-1], points_m=_grid(z))
    down = Pose.from_rotvec([0.0, 0.0, 0.2], [np.pi, 0.0, 0.0])  # tool z axis along -z of the world
    rng = np.random.default_rng(0)
    contacts = []
    for _ in range(20):
        world = np.c_[rng.uniform(-0.1, 0.1, (5, 2)), np.zeros(5)]
        contacts.append(down.inverse().apply(world))
    still = SpatialOdometry(np.zeros(3), np.zeros(3), 1.0)
    library = recognition.load_surface_library(files, ["low", "high"])
    assert library.names == ("low", "high")
    targets = recognition.surface_targets(library, down, [None] + [still] * 19, contacts)
    assert targets.shape == (20,)
    assert set(targets.tolist()) <= {-1, 0}
    assert np.sum(targets == 0) >= 10  # after the window fills, every whisk


@settings(max_examples=20, deadline=None)
@given(st.one_of(st.just(-0.1), st.just(10.5), st.just(float("nan")), st.just(float("inf")), st.just(True), st.just("1")))
def test_bad_odometry_scales_are_refused_before_any_work(tmp_path_factory, scale) -> None:
    from cansim.studies import ch5_object_maps

    out = tmp_path_factory.mktemp("rec") / "out"
    with pytest.raises(ConfigError):
        recognition.run(out, objects=["mug"], novel=[], odometry_scale=scale, progress=False)
    assert not out.exists()
    with pytest.raises(ConfigError):
        ch5_object_maps.StudyConfig(2, 0.3, {}, None, 0, odometry_scale=scale)


def test_odometry_noise_scales_the_thesis_model() -> None:
    """Scale 1 is Eq 6.4-6.11's noise exactly (2.5 deg per Euler angle, 1 cm); 0.25 a quarter of each."""
    import math

    from cansim.studies.ch5_object_maps import odometry_noise
    from whisker_io.sim.odometry_noise import OdometryNoise

    assert odometry_noise(1.0) == OdometryNoise()
    q = odometry_noise(0.25)
    assert q.euler_std_rad == pytest.approx(math.radians(2.5) / 4) and q.displacement_std_m == pytest.approx(0.0025)
    assert q.angular_speed_mean_rad_s == OdometryNoise().angular_speed_mean_rad_s


@settings(max_examples=15, deadline=None)
@given(st.sampled_from(["missing", "not_npz", "no_points", "bad_shape"]))
def test_bad_surface_files_raise_typed_errors(tmp_path_factory, kind) -> None:
    from whisker_io.errors import CorruptFileError, InvalidInputError, ShapeError

    d = tmp_path_factory.mktemp("surf")
    f = d / "s.npz"
    if kind == "not_npz":
        f.write_bytes(b"not a zip")
    elif kind == "no_points":
        np.savez_compressed(f, other=np.zeros(3))
    elif kind == "bad_shape":
        np.savez_compressed(f, points_m=np.zeros((5, 2)))
    with pytest.raises((InvalidInputError, CorruptFileError, ShapeError)):
        recognition.load_surface_library([f], ["x"])
