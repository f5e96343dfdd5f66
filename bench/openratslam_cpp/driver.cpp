// Side-by-side driver for OpenRatSLAM's C++ core (bench/cpp_compare.py builds and runs it).
//
// This file is cansim's own; it only calls the public classes of OpenRatSLAM's
// src/ratslam/posecell_network.cpp and src/ratslam/experience_map.cpp, which are compiled
// from the user's checkout (never copied into this repository):
//
//   g++ -O2 -I CHECKOUT/src driver.cpp CHECKOUT/src/ratslam/posecell_network.cpp \
//       CHECKOUT/src/ratslam/experience_map.cpp -o openratslam_driver
//
// Usage: openratslam_driver SETTINGS.ini INPUT.csv OUTPUT.csv
//
// SETTINGS.ini: OpenRatSLAM's own config format; the [ratslam] section is handed to both
// constructors (pc_dim_xy, pc_dim_th, pc_cell_x_size ...; absent keys take the C++ defaults).
//
// INPUT.csv: the format of tests/data/openratslam_cpp_trace.csv. Lines starting with '#' or
// 'kind' and rows not starting with 'S' are skipped; of an 'S' row only the first seven
// fields are read: S,has_vt,vt_id,vt_rad,vtrans,vrot,dt (floats decimal or C99 hex). View
// ids must be first-seen numbered (a new view is the number of views seen so far), as
// OpenRatSLAM's local view cells number them.
//
// Per step, as OpenRatSLAM's ROS nodes drive the two classes: on_view_template (when
// has_vt), the pose cells' on_odo, get_action, the map's on_odo, the action
// (CREATE_NODE: on_create_experience + on_set_experience(id, 0); CREATE_EDGE:
// on_create_link + on_set_experience(id, rel); SET_NODE: on_set_experience(id, rel)) and
// the map's iterate() - the last two only when get_action() returned an action, since the
// pose-cell node publishes only then and the map node relaxes in its action callback.
//
// OUTPUT.csv: the trace's format, floats as C99 hex (%a): one 'S' row per step (the inputs,
// then best_x, best_y, best_th, exp_id, n_exp, n_links, action), then the final experiences
// ('E': x_m, y_m, th_rad) and links ('L': from, to, d, heading_rad, facing_rad, delta_time_s).
//
// stdout: one line "loop_s SECONDS steps N experiences E links L". SECONDS is the step loop
// alone, timed with std::chrono::steady_clock: reading the input, building the two objects
// and writing the output are outside it. Exit status 2 on bad arguments or input.

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <boost/property_tree/ini_parser.hpp>
#include <boost/property_tree/ptree.hpp>

#include "ratslam/experience_map.h"
#include "ratslam/posecell_network.h"

namespace {

struct StepInput {
  int has_vt;
  unsigned int vt_id;
  double vt_rad, vtrans, vrot, dt;
};

struct StepOutput {
  double x, y, th;
  int exp_id, n_exp, n_links, action;
};

[[noreturn]] void fail(const std::string &msg) {
  std::cerr << "openratslam_driver: " << msg << std::endl;
  std::exit(2);
}

double parse_double(const std::string &s, int line_no) {
  char *end = nullptr;
  double v = std::strtod(s.c_str(), &end);  // C99: accepts hex floats
  if (s.empty() || *end != '\0') fail("line " + std::to_string(line_no) + ": not a number: '" + s + "'");
  return v;
}

std::vector<StepInput> read_inputs(const char *path) {
  std::ifstream in(path);
  if (!in) fail(std::string("cannot open input ") + path);
  std::vector<StepInput> rows;
  std::string line;
  int line_no = 0;
  unsigned int n_views = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#' || line.compare(0, 4, "kind") == 0 || line[0] != 'S') continue;
    std::vector<std::string> f;
    std::stringstream ss(line);
    std::string item;
    while (std::getline(ss, item, ',')) f.push_back(item);
    if (f.size() < 7) fail("line " + std::to_string(line_no) + ": an S row needs 7 fields");
    StepInput r;
    r.has_vt = static_cast<int>(parse_double(f[1], line_no));
    double vt = parse_double(f[2], line_no);
    if (vt < 0) fail("line " + std::to_string(line_no) + ": negative view id");
    r.vt_id = static_cast<unsigned int>(vt);
    r.vt_rad = parse_double(f[3], line_no);
    r.vtrans = parse_double(f[4], line_no);
    r.vrot = parse_double(f[5], line_no);
    r.dt = parse_double(f[6], line_no);
    if (r.has_vt) {
      if (r.vt_id > n_views)
        fail("line " + std::to_string(line_no) + ": view id " + std::to_string(r.vt_id) +
             " skips ids; a new view must be numbered " + std::to_string(n_views));
      if (r.vt_id == n_views) ++n_views;
    }
    rows.push_back(r);
  }
  if (rows.empty()) fail(std::string("no S rows in ") + path);
  return rows;
}

}  // namespace

int main(int argc, char **argv) {
  if (argc != 4) fail("usage: openratslam_driver SETTINGS.ini INPUT.csv OUTPUT.csv");
  boost::property_tree::ptree settings;
  try {
    boost::property_tree::read_ini(argv[1], settings);
  } catch (const std::exception &e) {
    fail(std::string("cannot read settings: ") + e.what());
  }
  boost::property_tree::ptree ratslam_settings = settings.get_child("ratslam", boost::property_tree::ptree());
  const std::vector<StepInput> inputs = read_inputs(argv[2]);
  std::vector<StepOutput> outputs(inputs.size());

  ratslam::PosecellNetwork pc(ratslam_settings);
  ratslam::ExperienceMap em(ratslam_settings);

  const auto t0 = std::chrono::steady_clock::now();
  for (std::size_t k = 0; k < inputs.size(); ++k) {
    const StepInput &in = inputs[k];
    if (in.has_vt) pc.on_view_template(in.vt_id, in.vt_rad);
    const int src_id = static_cast<int>(pc.get_current_exp_id());
    pc.on_odo(in.vtrans, in.vrot, in.dt);
    const ratslam::PosecellNetwork::PosecellAction action = pc.get_action();
    em.on_odo(in.vtrans, in.vrot, in.dt);
    if (action != ratslam::PosecellNetwork::NO_ACTION) {
      const int dest_id = static_cast<int>(pc.get_current_exp_id());
      const double rel_rad = pc.get_relative_rad();
      switch (action) {
        case ratslam::PosecellNetwork::CREATE_NODE:
          em.on_create_experience(dest_id);
          em.on_set_experience(dest_id, 0);
          break;
        case ratslam::PosecellNetwork::CREATE_EDGE:
          em.on_create_link(src_id, dest_id, rel_rad);
          em.on_set_experience(dest_id, rel_rad);
          break;
        case ratslam::PosecellNetwork::SET_NODE:
          em.on_set_experience(dest_id, rel_rad);
          break;
        default:
          break;
      }
      em.iterate();  // the map node relaxes on each published action, as its action callback does
    }
    StepOutput &out = outputs[k];
    out.x = pc.x();
    out.y = pc.y();
    out.th = pc.th();
    out.exp_id = em.get_current_id();
    out.n_exp = em.get_num_experiences();
    out.n_links = em.get_num_links();
    out.action = static_cast<int>(action);
  }
  const auto t1 = std::chrono::steady_clock::now();
  const double loop_s = std::chrono::duration<double>(t1 - t0).count();

  FILE *fo = std::fopen(argv[3], "w");
  if (!fo) fail(std::string("cannot write ") + argv[3]);
  std::fprintf(fo, "# OpenRatSLAM C++ core driven by bench/openratslam_cpp/driver.cpp; floats C99 hex\n");
  std::fprintf(fo, "kind,has_vt,vt_id,vt_rad,vtrans,vrot,dt,best_x,best_y,best_th,exp_id,n_exp,n_links,action\n");
  for (std::size_t k = 0; k < inputs.size(); ++k) {
    const StepInput &in = inputs[k];
    const StepOutput &o = outputs[k];
    std::fprintf(fo, "S,%d,%u,%a,%a,%a,%a,%a,%a,%a,%d,%d,%d,%d\n", in.has_vt, in.has_vt ? in.vt_id : 0u,
                 in.vt_rad, in.vtrans, in.vrot, in.dt, o.x, o.y, o.th, o.exp_id, o.n_exp, o.n_links, o.action);
  }
  for (int i = 0; i < em.get_num_experiences(); ++i) {
    const ratslam::Experience *e = em.get_experience(i);
    std::fprintf(fo, "E,%a,%a,%a\n", e->x_m, e->y_m, e->th_rad);
  }
  for (int i = 0; i < em.get_num_links(); ++i) {
    const ratslam::Link *l = em.get_link(i);
    std::fprintf(fo, "L,%d,%d,%a,%a,%a,%a\n", l->exp_from_id, l->exp_to_id, l->d, l->heading_rad, l->facing_rad,
                 l->delta_time_s);
  }
  std::fclose(fo);
  std::printf("loop_s %.9f steps %zu experiences %d links %d\n", loop_s, inputs.size(), em.get_num_experiences(),
              em.get_num_links());
  return 0;
}
