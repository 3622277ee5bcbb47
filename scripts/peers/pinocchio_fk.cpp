// Pinocchio's side of scripts/bench-peers.sh: builds a Pinocchio model straight
// from a DH table exported by kinserve (crates/kinserve-kinematics/examples/
// peer_fk.rs, `export`), checks Pinocchio's poses against kinserve's on every
// exported configuration BEFORE timing (exit 1 on any mismatch), then times
//   single: forwardKinematics + updateFramePlacement(tool), one configuration
//   batch:  the same over all configurations, each pose copied out, per pose
//   frames: forwardKinematics alone (every joint placement data.oMi)
// and prints `pinocchio ROBOT single|batch|frames NS` (ns per pose, median of 7
// samples, same calibration as peer_fk.rs).
//
// Headers only (Pinocchio from PyPI `pin`'s cmeel.prefix, Eigen from Debian's
// libeigen3-dev); nothing from the wheel's prebuilt libraries is linked, so the
// whole program is compiled with one set of flags:
//   g++ -std=c++17 -O3 -march=native -DNDEBUG -I$PREFIX/include -I/usr/include/eigen3 \
//       scripts/peers/pinocchio_fk.cpp -o pinocchio_fk
//   ./pinocchio_fk DIR ROBOT...
//
// The DH rows become joints as follows (revolute RZ, prismatic PZ; a fixed row
// folds into the constant placement around it):
//   standard  A_i = Rz(θ_i+q) Tz(d_i) Tx(a_i) Rx(α_i) = M(q) · C_i,  C_i = Rz(θ_i) Tz(d_i) Tx(a_i) Rx(α_i)
//   modified  A_i = Rx(α_i) Tx(a_i) Rz(θ_i+q) Tz(d_i) = C_i · M(q),  C_i = Rx(α_i) Tx(a_i) Rz(θ_i) Tz(d_i)
// where M(q) is Rz(q) (revolute) or Tz(q) (prismatic): Rz(θ) and Tz(·) commute
// with M(q). So T = base · Π A_i · tool is a product of constants and joint
// motions, and each joint's placement is the constant product since the last joint;
// the tool is an operational frame on the last joint with the trailing constant
// product times the tool transform.
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/multibody.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace pin = pinocchio;
using SE3 = pin::SE3;

template <class T> inline void keep(T const &v) { asm volatile("" : : "g"(&v) : "memory"); }

struct Row {
  char kind;
  double a, alpha, d, theta;
};

struct Exported {
  std::string name, convention;
  std::vector<Row> rows;
  SE3 base, tool;
  int n = 0, dof = 0, frame_checks = 0, frames_per = 0;
  std::vector<Eigen::VectorXd> q;
  std::vector<SE3> poses;
  std::vector<std::vector<SE3>> frames;
};

static SE3 read_se3(std::istream &in) {
  Eigen::Matrix3d r;
  Eigen::Vector3d p;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) in >> r(i, j);
  for (int i = 0; i < 3; ++i) in >> p(i);
  return SE3(r, p);
}

static void expect(std::istream &in, const char *word) {
  std::string w;
  in >> w;
  if (w != word) {
    std::cerr << "export file: expected '" << word << "', found '" << w << "'\n";
    std::exit(2);
  }
}

static Exported read_export(const std::string &path) {
  std::ifstream in(path);
  if (!in) {
    std::cerr << "cannot open " << path << "\n";
    std::exit(2);
  }
  Exported e;
  int rows;
  expect(in, "robot");
  in >> e.name;
  expect(in, "convention");
  in >> e.convention;
  expect(in, "rows");
  in >> rows;
  for (int i = 0; i < rows; ++i) {
    Row r;
    in >> r.kind >> r.a >> r.alpha >> r.d >> r.theta;
    e.rows.push_back(r);
  }
  expect(in, "base");
  e.base = read_se3(in);
  expect(in, "tool");
  e.tool = read_se3(in);
  expect(in, "configs");
  in >> e.n >> e.dof;
  for (int i = 0; i < e.n; ++i) {
    Eigen::VectorXd q(e.dof);
    for (int j = 0; j < e.dof; ++j) in >> q(j);
    e.q.push_back(q);
  }
  expect(in, "poses");
  int np;
  in >> np;
  for (int i = 0; i < np; ++i) e.poses.push_back(read_se3(in));
  expect(in, "frames");
  in >> e.frame_checks >> e.frames_per;
  for (int i = 0; i < e.frame_checks; ++i) {
    std::vector<SE3> f;
    for (int j = 0; j < e.frames_per; ++j) f.push_back(read_se3(in));
    e.frames.push_back(f);
  }
  if (!in) {
    std::cerr << path << ": truncated export file\n";
    std::exit(2);
  }
  return e;
}

static SE3 rot_z(double t) { return SE3(Eigen::AngleAxisd(t, Eigen::Vector3d::UnitZ()).toRotationMatrix(), Eigen::Vector3d::Zero()); }
static SE3 rot_x(double t) { return SE3(Eigen::AngleAxisd(t, Eigen::Vector3d::UnitX()).toRotationMatrix(), Eigen::Vector3d::Zero()); }
static SE3 trans(double x, double y, double z) { return SE3(Eigen::Matrix3d::Identity(), Eigen::Vector3d(x, y, z)); }

// The constant part C_i of a row (see the header), or the whole fixed link.
static SE3 constant(const std::string &conv, const Row &r) {
  if (conv == "standard") return rot_z(r.theta) * trans(0, 0, r.d) * trans(r.a, 0, 0) * rot_x(r.alpha);
  return rot_x(r.alpha) * trans(r.a, 0, 0) * rot_z(r.theta) * trans(0, 0, r.d);
}

// Builds the model; returns the tool frame's index. `row_of_joint[j]` is the
// DH row of Pinocchio joint j+1.
static pin::FrameIndex build(const Exported &e, pin::Model &model, std::vector<int> &row_of_joint) {
  const bool standard = e.convention == "standard";
  SE3 acc = e.base;
  pin::JointIndex parent = 0;
  for (size_t i = 0; i < e.rows.size(); ++i) {
    const Row &r = e.rows[i];
    const SE3 c = constant(e.convention, r);
    if (r.kind == 'F') {
      acc = acc * c;
      continue;
    }
    if (!standard) acc = acc * c;
    const std::string name = "j" + std::to_string(i);
    if (r.kind == 'R')
      parent = model.addJoint(parent, pin::JointModelRZ(), acc, name);
    else
      parent = model.addJoint(parent, pin::JointModelPZ(), acc, name);
    row_of_joint.push_back(int(i));
    acc = standard ? c : SE3::Identity();
  }
  return model.addFrame(pin::Frame("tool", parent, acc * e.tool, pin::OP_FRAME));
}

static double diff(const SE3 &a, const SE3 &b) {
  return std::max((a.rotation() - b.rotation()).cwiseAbs().maxCoeff(),
                  (a.translation() - b.translation()).cwiseAbs().maxCoeff());
}

// Pinocchio against kinserve: the tool pose of every configuration, and the
// origin of every joint frame against the DH frame it sits on (standard: the
// frame before the joint's row, modified: the frame after it).
static double check(const Exported &e, const pin::Model &model, pin::Data &data, pin::FrameIndex fid,
                    const std::vector<int> &row_of_joint) {
  double worst = 0;
  for (int i = 0; i < e.n; ++i) {
    pin::forwardKinematics(model, data, e.q[i]);
    worst = std::max(worst, diff(pin::updateFramePlacement(model, data, fid), e.poses[i]));
  }
  const bool standard = e.convention == "standard";
  for (int i = 0; i < e.frame_checks; ++i) {
    pin::forwardKinematics(model, data, e.q[i]);
    for (size_t j = 0; j < row_of_joint.size(); ++j) {
      const SE3 &f = e.frames[i][row_of_joint[j] + (standard ? 0 : 1)];
      worst = std::max(worst, (data.oMi[j + 1].translation() - f.translation()).cwiseAbs().maxCoeff());
    }
  }
  return worst;
}

template <class F> static double time_ns(size_t per_call, F f) {
  using clock = std::chrono::steady_clock;
  const auto sample = std::chrono::milliseconds(40);
  size_t calls = 1;
  for (;;) {
    auto t = clock::now();
    for (size_t c = 0; c < calls; ++c) f();
    if (clock::now() - t >= sample / 4 || calls >= (size_t(1) << 30)) break;
    calls *= 2;
  }
  calls *= 4;
  std::vector<double> s;
  for (int k = 0; k < 7; ++k) {
    auto t = clock::now();
    for (size_t c = 0; c < calls; ++c) f();
    s.push_back(std::chrono::duration<double, std::nano>(clock::now() - t).count() / double(calls * per_call));
  }
  std::sort(s.begin(), s.end());
  return s[3];
}

int main(int argc, char **argv) {
  if (argc < 3) {
    std::cerr << "usage: pinocchio_fk DIR ROBOT...\n";
    return 2;
  }
  for (int a = 2; a < argc; ++a) {
    const Exported e = read_export(std::string(argv[1]) + "/" + argv[a] + ".txt");
    pin::Model model;
    std::vector<int> row_of_joint;
    const pin::FrameIndex fid = build(e, model, row_of_joint);
    pin::Data data(model);
    if (model.nq != e.dof) {
      std::cerr << e.name << ": model has " << model.nq << " joints, export " << e.dof << "\n";
      return 1;
    }
    const double worst = check(e, model, data, fid, row_of_joint);
    std::fprintf(stderr, "pinocchio %s: max |difference| from kinserve over %d poses: %.3g\n", e.name.c_str(), e.n, worst);
    if (!(worst <= 1e-9)) {
      std::fprintf(stderr, "pinocchio %s: poses disagree with kinserve; not timing\n", e.name.c_str());
      return 1;
    }
    const size_t set = 16;
    size_t i = 0;
    const double single = time_ns(1, [&] {
      i = (i + 1) % set;
      pin::forwardKinematics(model, data, e.q[i]);
      keep(pin::updateFramePlacement(model, data, fid));
    });
    std::vector<SE3> out(e.n);
    const double batch = time_ns(e.n, [&] {
      for (int k = 0; k < e.n; ++k) {
        pin::forwardKinematics(model, data, e.q[k]);
        out[k] = pin::updateFramePlacement(model, data, fid);
      }
      keep(out);
    });
    const double frames = time_ns(1, [&] {
      i = (i + 1) % set;
      pin::forwardKinematics(model, data, e.q[i]);
      keep(data.oMi);
    });
    std::printf("pinocchio %s single %.2f\npinocchio %s batch %.2f\npinocchio %s frames %.2f\n", e.name.c_str(), single,
                e.name.c_str(), batch, e.name.c_str(), frames);
  }
  return 0;
}
