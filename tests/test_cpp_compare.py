"""bench/cpp_compare.py: the side-by-side harness against OpenRatSLAM's C++ core (issue 26 item 6).

OpenRatSLAM's source is not in the repository. The fast tests check the harness itself:
its errors without a checkout / Boost / compiler, the generated routes, the input and
output files, and the driver's call sequence, compiled against a small stand-in
"checkout" whose classes do plain, hand-checkable arithmetic. The slow test runs the real
comparison when ``CANSIM_OPENRATSLAM_SRC`` points to a checkout of davidmball/ratslam.
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parent.parent
_spec = importlib.util.spec_from_file_location("cpp_compare", ROOT / "bench" / "cpp_compare.py")
cc = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("cpp_compare", cc)  # its dataclasses look their module up there
_spec.loader.exec_module(cc)


# ----------------------------------------------------------------------------- errors
def test_no_checkout_says_how_to_give_one():
    with pytest.raises(cc.HarnessError, match="CANSIM_OPENRATSLAM_SRC"):
        cc.check_checkout(None)


def test_a_missing_or_wrong_folder_is_named(tmp_path):
    with pytest.raises(cc.HarnessError, match="does not exist"):
        cc.check_checkout(tmp_path / "nowhere")
    (tmp_path / "src" / "ratslam").mkdir(parents=True)
    (tmp_path / "src" / "ratslam" / "posecell_network.cpp").write_text("")
    with pytest.raises(cc.HarnessError, match=r"not an OpenRatSLAM checkout: missing src/ratslam/posecell_network\.h"):
        cc.check_checkout(tmp_path)


def test_missing_boost_says_what_to_install(tmp_path):
    with pytest.raises(cc.HarnessError, match=r"apt-get install libboost-dev.*--boost-include"):
        cc.find_boost(tmp_path)


def test_main_exits_2_with_the_reason(tmp_path, capsys):
    assert cc.main(["--openratslam", str(tmp_path / "nowhere"), "--routes", "trace"]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_a_missing_compiler_is_named(tmp_path):
    with pytest.raises(cc.HarnessError, match="compiler 'no-such-c\\+\\+' not found"):
        cc.compile_driver(tmp_path, tmp_path, None, cxx="no-such-c++")


# ----------------------------------------------------------------------------- routes and files
def _first_seen(ids):
    seen = 0
    for i in ids:
        if i > seen:
            return False
        seen += i == seen
    return True


@settings(max_examples=25, deadline=None)
@given(steps=st.integers(1, 400), seed=st.integers(0, 2**32 - 1), route=st.sampled_from(["circle", "walk"]))
def test_generated_routes_number_views_first_seen_and_move_under_a_cell(steps, seed, route):
    make = cc.circle_inputs if route == "circle" else cc.walk_inputs
    rows = make(steps, seed)
    assert rows == make(steps, seed) and len(rows) == steps  # deterministic under the seed
    assert _first_seen([r[1] for r in rows if r[0]])
    assert all(0 < r[3] * r[5] < 1.0 and math.isfinite(r[4]) for r in rows)  # < 1 cell of 1 m per step


def test_the_walk_revisits_more_places_than_the_circle():
    circle, walk = cc.circle_inputs(2000, 0), cc.walk_inputs(2000, 0)
    assert len({r[1] for r in circle if r[0]}) == 32  # the circle's 32 segments
    assert len({r[1] for r in walk}) == 36  # the 6 x 6 tiles of the room


@settings(max_examples=25, deadline=None)
@given(rows=st.lists(st.tuples(st.integers(0, 1), st.integers(0, 50), *[st.floats(-1e3, 1e3)] * 4), min_size=1, max_size=30))
def test_inputs_round_trip_bit_for_bit(tmp_path_factory, rows):
    rows = [(h, v if h else 0, a, b, c, d) for h, v, a, b, c, d in rows]
    path = tmp_path_factory.mktemp("io") / "in.csv"
    cc.write_inputs(path, rows)
    back = cc.trace_inputs(path)
    assert np.array_equal(np.array(back, dtype=np.float64).view(np.uint64), np.array(rows, dtype=np.float64).view(np.uint64))


def test_the_trace_has_its_300_steps():
    rows = cc.trace_inputs()
    assert len(rows) == 300 and rows[0][:2] == (1, 0)
    out = cc.read_output(cc.TRACE)
    assert out.best.shape == (300, 3) and out.counts[-1].tolist() == [186, 187, 224, 1]
    assert out.poses.shape == (187, 3) and out.links.shape == (224, 6)


def test_first_difference_compares_bits():
    out = cc.read_output(cc.TRACE)
    same = cc.RunOutput(out.best.copy(), out.counts.copy(), out.poses.copy(), out.links.copy())
    assert cc.first_difference(out, same) is None
    same.poses[5, 2] = np.nextafter(same.poses[5, 2], np.inf)
    assert cc.first_difference(out, same).startswith("poses row 5")
    zero = cc.RunOutput(np.zeros((1, 3)), np.zeros((1, 4), dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 6)))
    neg = cc.RunOutput(-np.zeros((1, 3)), zero.counts, zero.poses, zero.links)
    assert cc.first_difference(zero, neg).startswith("best row 0")  # -0.0 is not 0.0 bit for bit


# ----------------------------------------------------------------------------- the driver, on a stand-in
# A stand-in for OpenRatSLAM's two classes with the public signatures the driver calls and
# trivial arithmetic: x sums vtrans * dt, y sums vrot * dt, th is the last view id; a new view
# makes CREATE_NODE, a seen one other than the current SET_NODE, none NO_ACTION. The map
# counts its iterate() calls in every experience's th_rad.
_PC_H = r"""
#include <boost/property_tree/ptree.hpp>
#include <vector>
namespace ratslam {
class PosecellNetwork {
 public:
  enum PosecellAction {NO_ACTION = 0, CREATE_NODE, CREATE_EDGE, SET_NODE};
  PosecellNetwork(boost::property_tree::ptree s) : bx(0), by(0), bth(0), n_views(0), cur(0), act(NO_ACTION) {
    bx = s.get<double>("pc_dim_xy", 0) * 1000.0;
  }
  void on_view_template(unsigned int vt, double rad) {
    if (vt >= n_views) { n_views = vt + 1; act = CREATE_NODE; cur = vt; }
    else if (vt != cur) { act = SET_NODE; cur = vt; }
    bth = vt;
  }
  void on_odo(double v, double w, double dt) { bx += v * dt; by += w * dt; }
  PosecellAction get_action() { PosecellAction a = act; act = NO_ACTION; return a; }
  double x() { return bx; } double y() { return by; } double th() { return bth; }
  unsigned int get_current_exp_id() { return cur; }
  double get_relative_rad() { return 0.0; }
 private:
  double bx, by, bth; unsigned int n_views, cur; PosecellAction act;
};
}
"""
_EM_H = r"""
#include <boost/property_tree/ptree.hpp>
#include <vector>
namespace ratslam {
struct Link { double d, heading_rad, facing_rad; int exp_to_id, exp_from_id; double delta_time_s; };
struct Experience { int id; double x_m, y_m, th_rad; };
class ExperienceMap {
 public:
  ExperienceMap(boost::property_tree::ptree) : cur(-1), iterations(0) {}
  int on_create_experience(unsigned int id) { Experience e = {(int)id, (double)id, 0.0, 0.0}; exps.push_back(e); return id; }
  bool on_create_link(int a, int b, double r) { return true; }
  int on_set_experience(int id, double r) { cur = id; return 1; }
  void on_odo(double, double, double) {}
  bool iterate() { ++iterations; for (size_t i = 0; i < exps.size(); ++i) exps[i].th_rad = iterations; return true; }
  Experience *get_experience(int i) { return &exps[i]; }
  Link *get_link(int i) { return &links[i]; }
  int get_num_experiences() { return exps.size(); }
  int get_num_links() { return links.size(); }
  int get_current_id() { return cur; }
 private:
  std::vector<Experience> exps; std::vector<Link> links; int cur, iterations;
};
}
"""


@pytest.fixture(scope="module")
def stand_in_driver(tmp_path_factory):
    if shutil.which("g++") is None:
        pytest.skip("g++ not installed: the driver cannot be compiled here")
    try:
        boost = cc.find_boost()
    except cc.HarnessError as e:
        pytest.skip(str(e))
    root = tmp_path_factory.mktemp("stand_in")
    (root / "src" / "ratslam").mkdir(parents=True)
    (root / "src" / "utils").mkdir()
    (root / "src" / "ratslam" / "posecell_network.h").write_text(_PC_H)
    (root / "src" / "ratslam" / "experience_map.h").write_text(_EM_H)
    (root / "src" / "ratslam" / "posecell_network.cpp").write_text('#include "posecell_network.h"\n')
    (root / "src" / "ratslam" / "experience_map.cpp").write_text('#include "experience_map.h"\n')
    (root / "src" / "utils" / "utils.h").write_text("")
    return cc.compile_driver(cc.check_checkout(root), root / "build", boost)


@pytest.mark.slow  # compiles C++ (fast loop <= 4 min)
def test_the_driver_makes_the_calls_in_order_and_writes_the_trace_format(stand_in_driver, tmp_path):
    rows = [(1, 0, 0.0, 0.5, 0.25, 1.0), (0, 0, 0.0, 0.25, -0.5, 2.0), (1, 1, 0.0, 0.125, 0.0, 1.0),
            (1, 0, 0.0, 0.0, 1.0, 0.5), (1, 0, 0.0, 1.0, 0.0, 1.0)]
    ini, inp, out = tmp_path / "s.ini", tmp_path / "in.csv", tmp_path / "out.csv"
    ini.write_text(cc.settings_ini(21, 36, 1.0))
    cc.write_inputs(inp, rows)
    loop_s, got = cc.run_cpp(stand_in_driver, ini, inp, out)
    assert 0.0 <= loop_s < 1.0
    # by hand: x = 21000 + running sum of v * dt; y = running sum of w * dt; th = last view id
    assert got.best.tolist() == [[21000.5, 0.25, 0.0], [21001.0, -0.75, 0.0], [21001.125, -0.75, 1.0],
                                 [21001.125, -0.25, 0.0], [21002.125, -0.25, 0.0]]
    # actions: new view 0, none, new view 1, back to 0 (SET_NODE), same view (none)
    assert got.counts.tolist() == [[0, 1, 0, 1], [0, 1, 0, 0], [1, 2, 0, 1], [0, 2, 0, 3], [0, 2, 0, 0]]
    assert got.poses.tolist() == [[0.0, 0.0, 3.0], [1.0, 0.0, 3.0]]  # iterate() ran on the 3 actions only
    assert got.links.shape == (0, 6)


@pytest.mark.slow  # compiles C++ (fast loop <= 4 min)
def test_the_driver_refuses_view_ids_that_skip(stand_in_driver, tmp_path):
    ini, inp = tmp_path / "s.ini", tmp_path / "in.csv"
    ini.write_text(cc.settings_ini(21, 36, 1.0))
    cc.write_inputs(inp, [(1, 0, 0.0, 0.1, 0.0, 1.0), (1, 2, 0.0, 0.1, 0.0, 1.0)])
    with pytest.raises(cc.HarnessError, match="view id 2 skips ids; a new view must be numbered 1"):
        cc.run_cpp(stand_in_driver, ini, inp, tmp_path / "out.csv")


@pytest.mark.slow  # compiles C++ (fast loop <= 4 min)
def test_a_broken_checkout_fails_to_compile_with_the_compiler_message(stand_in_driver, tmp_path):
    root = stand_in_driver.parent.parent
    broken = tmp_path / "broken"
    shutil.copytree(root / "src", broken / "src")
    (broken / "src" / "ratslam" / "experience_map.cpp").write_text("this is not C++;\n")
    with pytest.raises(cc.HarnessError, match="compiling the driver failed"):
        cc.compile_driver(cc.check_checkout(broken), tmp_path / "build", None)


# ----------------------------------------------------------------------------- the real thing
@pytest.mark.slow
def test_side_by_side_with_openratslam_is_bit_identical(tmp_path, capsys):
    src = os.environ.get("CANSIM_OPENRATSLAM_SRC")
    if not src:
        pytest.skip("CANSIM_OPENRATSLAM_SRC is not set: point it at a checkout of davidmball/ratslam to run "
                    "the side-by-side comparison (it also needs g++ and the Boost headers)")
    out = tmp_path / "ratios.json"
    code = cc.main(["--openratslam", src, "--routes", "trace,circle,walk", "--steps", "400", "--grid", "21",
                    "--reps", "1", "--build-dir", str(tmp_path), "--json", str(out)])
    printed = capsys.readouterr()
    assert code == 0, printed.err[-2000:]
    res = json.loads(out.read_text())
    assert [c["route"] for c in res["cases"]] == ["trace", "circle", "walk"]
    assert all(c["parity_identical"] for c in res["cases"]) and res["cases"][0]["trace_identical"] is True
    assert all(c["ratio_generic"] > 0 and c["experiences"]["cpp"] > 1 for c in res["cases"])
    assert "load average" in printed.out and res["meta"]["cansim_commit"]
