// Pinocchio reference, header-only build: the same measurement as fk_bench.cpp, but the hp20 model
// is built in code (the joint types, placements and limits that pinocchio's URDF parser makes of
// robots/hp20.urdf: RZ, RY, then RevoluteUnaligned for the four negative axes; tool0 frame on
// joint 6 with rotation rpy (0, π/2, 0)) so that no prebuilt pinocchio library is linked and the
// whole of forwardKinematics + updateFramePlacement can be compiled with -O3 -march=native.
// (fk_bench.cpp with -march=native crashes: the prebuilt URDF parser was compiled for another
// Eigen alignment.) Build and run: see BENCHMARKS.md, section kinematics.

#include <pinocchio/multibody.hpp>
#include <pinocchio/math.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <algorithm>
#include <chrono>
#include <iostream>
#include <random>

int main() {
  using namespace pinocchio;
  Model model;
  const double inf = std::numeric_limits<double>::infinity();
  auto add = [&](JointIndex parent, const auto& joint, double x, double y, double z, const char* name,
                 double lo, double hi) {
    Eigen::VectorXd big = Eigen::VectorXd::Constant(1, inf);
    return model.addJoint(parent, joint, SE3(Eigen::Matrix3d::Identity(), Eigen::Vector3d(x, y, z)), name, big,
                          big, Eigen::VectorXd::Constant(1, lo), Eigen::VectorXd::Constant(1, hi));
  };
  JointIndex j = 0;
  j = add(j, JointModelRZ(), 0, 0, 0.505, "joint_1_s", -3.1416, 3.1416);
  j = add(j, JointModelRY(), 0.15, 0, 0, "joint_2_l", -1.9199, 2.7053);
  j = add(j, JointModelRevoluteUnaligned(0, -1, 0), 0, 0, 0.76, "joint_3_u", -2.8798, 3.1416);
  j = add(j, JointModelRevoluteUnaligned(-1, 0, 0), 0, 0, 0.14, "joint_4_r", -3.4907, 3.4907);
  j = add(j, JointModelRevoluteUnaligned(0, -1, 0), 0.795, 0, 0, "joint_5_b", -2.4435, 2.4435);
  j = add(j, JointModelRevoluteUnaligned(-1, 0, 0), 0.105, 0, 0, "joint_6_t", -6.2832, 6.2832);
  auto fid = model.addFrame(
      Frame("tool0", j, SE3(rpy::rpyToMatrix(0.0, 1.5707963267948966, 0.0), Eigen::Vector3d::Zero()), OP_FRAME));
  Data data(model);
  std::mt19937_64 rng(20140101);
  std::vector<Eigen::VectorXd> qs;
  for (int i = 0; i < 256; ++i) {
    Eigen::VectorXd q(model.nq);
    for (int k = 0; k < model.nq; ++k) {
      double lo = std::max(model.lowerPositionLimit[k], -3.0), hi = std::min(model.upperPositionLimit[k], 3.0);
      double m = 0.05 * (hi - lo);
      q[k] = std::uniform_real_distribution<double>(lo + m, hi - m)(rng);
    }
    qs.push_back(q);
  }
  Eigen::Vector3d tip(0, 0, 0.15), acc = Eigen::Vector3d::Zero();
  std::vector<double> ns;
  const int N = 200000;
  for (int rep = 0; rep < 21; ++rep) {
    auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < N; ++i) {
      const auto& q = qs[i & 255];
      forwardKinematics(model, data, q);
      updateFramePlacement(model, data, fid);
      acc += data.oMf[fid].act(tip);
    }
    auto t1 = std::chrono::steady_clock::now();
    ns.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count() / N);
  }
  std::sort(ns.begin(), ns.end());
  std::cout << "nq " << model.nq << " median " << ns[10] << " ns min " << ns[0] << " ns (acc " << acc.transpose() << ")\n";
  forwardKinematics(model, data, Eigen::VectorXd::Zero(model.nq));
  updateFramePlacement(model, data, fid);
  std::cout << "zero pose tip " << data.oMf[fid].act(tip).transpose() << "\n";
}
