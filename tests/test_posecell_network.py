"""cansim.models.posecell_network: OpenRatSLAM's pose cells with the C++ arithmetic.

The reference is ``tests/data/openratslam_cpp_trace.csv``: 300 steps of the C++
core (pose cells + experience map) on odometry with backward motion,
multi-cell turns, missing views, revisits and panoramic view offsets. The
parity preset must reproduce every number in it bit for bit.
"""

import math
from pathlib import Path

import numpy as np
import pytest

from cansim.params import AttractorParams

from cansim.errors import ConfigError, InvalidInputError, ShapeError, ZeroActivityError
from cansim.local_view import LocalViewCells, LocalViewParams
from cansim.population import Population
from cansim.models.posecell_network import PosecellNetwork
from cansim.models.ratslam import RatSLAM, RatSLAMConfig
from maps.experience_map import ExperienceMap, MapConfig

TRACE = Path(__file__).parent / "data" / "openratslam_cpp_trace.csv"


def load_trace():
    steps, exps, links = [], [], []
    hx = float.fromhex
    with open(TRACE, encoding="ascii") as fh:
        for line in fh:
            if line.startswith(("#", "kind")):
                continue
            f = line.rstrip("\n").split(",")
            if f[0] == "S":
                steps.append((
                    bool(int(f[1])), int(f[2]), hx(f[3]), hx(f[4]), hx(f[5]), hx(f[6]),
                    (hx(f[7]), hx(f[8]), hx(f[9])), tuple(int(v) for v in f[10:14]),
                ))
            elif f[0] == "E":
                exps.append([hx(v) for v in f[1:4]])
            else:
                links.append([int(f[1]), int(f[2])] + [hx(v) for v in f[3:7]])
    return steps, np.array(exps), np.array(links)


def test_parity_preset_reproduces_the_cpp_core_bit_for_bit():
    steps, exps, links = load_trace()
    assert len(steps) == 300 and len(exps) > 100 and sum(s[7][3] == 2 for s in steps) > 20  # many loop closures
    slam = RatSLAM(RatSLAMConfig.openratslam(cell_size_m=0.25))
    em = slam.experience_map
    for k, (has_vt, vid, rad, vtrans, vrot, dt, best, counts) in enumerate(steps):
        s = slam.step(vtrans, vrot, dt, (vid, rad) if has_vt else None)
        assert s.best_pc == best, f"step {k}: decoded {s.best_pc} != C++ {best}"
        assert (s.exp_id, em.n_experiences, em.n_links, int(s.action)) == counts, f"step {k}"
    assert np.array_equal(em.poses, exps)
    ends, data = em.links
    assert np.array_equal(ends, links[:, :2].astype(np.int64))
    assert np.array_equal(data, links[:, 2:])


def test_a_lone_cell_decodes_just_below_its_index_as_in_cpp():
    # The C++ decodes with angle tables at (i + 1) and subtracts 1: a symmetric packet at
    # cell 10 gives 9.999999999999998, which (int) truncates to 9. The trace starts so.
    steps, _, _ = load_trace()
    pc = PosecellNetwork()
    assert tuple(pc.decode()) == (10.0, 10.0, 18.0)  # C++ starts from floor(n / 2), not a decode
    best = pc.step(0.0, 0.0, 1.0)
    assert best[0] < 10.0 and int(best[0]) == 9 and best[0] == pytest.approx(10.0, abs=1e-12)
    vtrans, vrot, dt = steps[0][3:6]
    assert tuple(PosecellNetwork(cell_size_m=0.25).step(vtrans, vrot, dt)) == steps[0][6]


def test_agrees_with_the_population_engine_without_views():
    rng = np.random.default_rng(3)
    cpp = PosecellNetwork(cell_size_m=0.5)
    pop = Population.openratslam(21, 36, 0.5, frame="openratslam", dtype=np.float64, backend="numpy")
    dims = np.array([21.0, 21.0, 36.0])
    for _ in range(150):
        v, w = rng.uniform(-0.2, 0.5), rng.normal(0.0, 0.2)
        a, b = cpp.step(v, w, 1.0), pop.step(v, w, 1.0)
        d = np.abs(a - b)
        assert np.all(np.minimum(d, dims - d) < 1e-9)
    assert np.allclose(cpp.activity, pop.activity, atol=1e-12)


def test_one_cell_translation_along_the_cpp_frame():
    # dir 0 moves +y, dir pi moves -y; a whole cell moves the mass exactly, and v = 0 is the identity
    from cansim.models import _posecell_kernels as k

    pc = PosecellNetwork()
    rot, cs, sn = pc._layer_tables[0.0]
    p = np.zeros((36, 21, 21))
    p[0, 4, 7] = 1.0
    p[18, 4, 7] = 2.0
    p[9, 4, 7] = 3.0
    q = p.copy()
    k.translate(q, rot, cs, sn, 0.0, np.ones(36, dtype=bool))
    assert np.array_equal(q, p)
    k.translate(q, rot, cs, sn, 1.0, np.ones(36, dtype=bool))
    assert q[0, 5, 7] == 1.0 and q[18, 3, 7] == 2.0 and q[0].sum() == 1.0 and q[18].sum() == 2.0
    assert q[9].sum() == pytest.approx(3.0, abs=1e-12) and q[9, 4, 7] < 1e-12  # 90 deg leaves along x


def test_translation_conserves_mass_except_the_cpp_corner_leak():
    # Away from row 0 / column 0 of the turned layer the four weights sum to 1. The C++ folds
    # the overflow column back only from row 1 on (and the overflow row from column 1 on), so a
    # cell in row 0 moving along +x loses its share w_se = v sin(a) (1 - v cos(a)) - kept here.
    from cansim.models import _posecell_kernels as k

    pc = PosecellNetwork(xy_cells=9, heading_cells=36)
    rot, cs, sn = pc._layer_tables[0.0]
    layer, a, v = 4, math.radians(40.0), 0.7  # 40 deg: no quarter turn, residual angle 40 deg
    assert rot[layer] == 0
    p = np.zeros((36, 9, 9))
    p[layer, 4, 4] = 1.0
    k.translate(p, rot, cs, sn, v, np.ones(36, dtype=bool))
    assert p[layer].sum() == pytest.approx(1.0, abs=1e-15)
    p = np.zeros((36, 9, 9))
    p[layer, 0, 8] = 1.0  # row 0, last column
    k.translate(p, rot, cs, sn, v, np.ones(36, dtype=bool))
    assert p[layer].sum() == pytest.approx(1.0 - v * math.sin(a) * (1.0 - v * math.cos(a)), abs=1e-15)
    assert p[layer, 1, 0] == pytest.approx(v * v * math.cos(a) * math.sin(a), abs=1e-15)  # the diagonal share wraps


def test_whole_cell_rotation_is_an_exact_roll():
    pc = PosecellNetwork()
    pc.activity = np.random.default_rng(1).random(pc.shape)
    before = pc._p.copy()
    pc._kernels.rotate_theta(pc._p, pc._tmp, -35, -35, 1.0, np.ones(36, dtype=bool))  # what vrot * dt = +2 pi / 36 produces
    assert np.array_equal(pc._p, np.roll(before, 1, axis=0))


def test_collapse_and_bad_input_leave_the_state_unchanged():
    pc = PosecellNetwork(params=AttractorParams(global_inhibition=1.0))
    before, best = pc.activity, pc.decode()
    with pytest.raises(ZeroActivityError):
        pc.step(0.1, 0.0, 1.0)
    pc = PosecellNetwork()
    pc.step(0.1, 0.1, 1.0)
    before, best = pc.activity, pc.decode()
    with pytest.raises(InvalidInputError, match="finite"):
        pc.step(float("nan"), 0.0, 1.0)
    with pytest.raises(InvalidInputError, match=r"\[0, 15876\)"):
        pc.step(0.0, 0.0, 1.0, injection=(np.array([15876]), np.array([0.1])))
    with pytest.raises(ShapeError):
        pc.activity = np.zeros((21, 21))
    assert np.array_equal(pc.activity, before) and np.array_equal(pc.decode(), best)


def test_injection_uses_x_y_theta_order():
    pc = PosecellNetwork()
    flat = np.ravel_multi_index((3, 15, 30), pc.shape)
    best = None
    for _ in range(40):  # a strong, repeated view drags the packet to cell (3, 15, 30)
        best = pc.step(0.0, 0.0, 1.0, injection=(np.array([flat]), np.array([0.5])))
    assert np.allclose(best, (3.0, 15.0, 30.0), atol=0.05)
    assert np.unravel_index(np.argmax(pc.activity), pc.shape) == (3, 15, 30)


@pytest.mark.parametrize(
    "kwargs,match",
    [({"params": AttractorParams(exc_sigma=1.5)}, "exc_sigma"), ({"params": AttractorParams(inh_width=4)}, "inh_width"),
     ({"heading_cells": 2}, "heading_cells"), ({"cell_size_m": 0.0}, "cell_size_m"),
     ({"params": AttractorParams(exc_width=(7, 7, 5))}, "exc_width")],
)
def test_bad_parameters_are_named(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        PosecellNetwork(**kwargs)


def test_engine_choice_in_the_config():
    assert isinstance(RatSLAM(RatSLAMConfig.openratslam()).pose_cells, PosecellNetwork)
    assert isinstance(RatSLAM(RatSLAMConfig.openratslam(pose_cells="population")).pose_cells, Population)
    with pytest.raises(ConfigError, match="float64"):
        RatSLAMConfig.openratslam(dtype="float32")
    with pytest.raises(ConfigError, match="pose_cells"):
        RatSLAMConfig(pose_cells="matlab")


def test_view_id_with_relative_rad_observation():
    slam = RatSLAM(RatSLAMConfig.openratslam())
    assert slam.step(0.0, 0.0, 1.0, (5, 0.3)).view_id == 0
    with pytest.raises(InvalidInputError, match="2 entries"):
        slam.step(0.0, 0.0, 1.0, (5, 0.3, 1))
    with pytest.raises(InvalidInputError, match="finite"):
        slam.step(0.0, 0.0, 1.0, (5, float("inf")))
    assert slam.iteration == 1


# ------------------------------------------------------------- C++ view-cell arithmetic
CPP = LocalViewParams(cpp_cells=True)


def cell_of(injection, shape=(21, 21, 36)):
    idx, _ = injection
    return tuple(int(v) for v in np.unravel_index(idx[0], shape)) if len(idx) else None


def test_cpp_cells_keep_raw_coordinates_and_skip_off_grid_cells():
    lv = LocalViewCells((21, 21, 36), CPP)
    lv.observe(0, (21.0, 4.5, 10.2))  # find_best may return n itself
    assert lv.locations[0, 0] == 21.0
    assert cell_of(lv.observe(0, (0, 0, 0))) is None and lv.last_energy > 0  # (int) 21 is outside: C++ skips
    wrapped = LocalViewCells((21, 21, 36), LocalViewParams())
    wrapped.observe(0, (21.0, 4.5, 10.2))
    assert cell_of(wrapped.observe(0, (0, 0, 0))) == (0, 4, 10)


@pytest.mark.parametrize("theta,offset,cell", [(35.5, 1.0, 0), (0.2, -1.0, 35), (36.0, 0.0, 0), (17.9, 0.0, 17)])
def test_cpp_cells_wrap_theta_once_and_truncate(theta, offset, cell):
    lv = LocalViewCells((21, 21, 36), CPP)
    lv.observe(0, (2.7, 3.2, theta))
    assert cell_of(lv.observe(0, (0, 0, 0), offset_cells=(0.0, 0.0, offset))) == (2, 3, cell)


def test_cpp_cells_need_a_3d_stored_truncating_grid():
    with pytest.raises(ShapeError):
        LocalViewCells((5,) * 6, CPP)
    with pytest.raises(InvalidInputError, match="cpp_cells"):
        LocalViewParams(cpp_cells=True, rounding="round")


# ------------------------------------------------------------- link timer
@pytest.mark.parametrize("since_start,expected", [(False, [2.0, 3.0]), (True, [2.0, 5.0])])
def test_link_time_since_start_reproduces_the_cpp_timer(since_start, expected):
    em = ExperienceMap(MapConfig(link_time_since_start=since_start, match_distance_cells=1.0))
    em.update((1.0, 1.0, 1.0), 0, 0)
    for pc, vt, seconds in (((5.0, 1.0, 1.0), 1, 2.0), ((9.0, 1.0, 1.0), 2, 3.0)):
        em.on_odo(0.1, 0.0, seconds)
        em.update(pc, vt, vt - 1)
    assert em.links[1][:, 3].tolist() == expected
