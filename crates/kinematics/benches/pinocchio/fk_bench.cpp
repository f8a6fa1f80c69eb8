// Pinocchio reference for `cargo bench -p kinematics` (fk/hp20): forwardKinematics +
// updateFramePlacement(tool0) + tip point, on 256 seeded joint vectors; median of 21 runs of
// 200000 calls. Build and run: see BENCHMARKS.md, section kinematics.

#include <pinocchio/parsers/urdf.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <chrono>
#include <random>
#include <algorithm>
#include <iostream>
int main(int argc, char** argv) {
  pinocchio::Model model;
  pinocchio::urdf::buildModel(argv[1], model);
  pinocchio::Data data(model);
  auto fid = model.getFrameId("tool0");
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
      pinocchio::forwardKinematics(model, data, q);
      pinocchio::updateFramePlacement(model, data, fid);
      acc += data.oMf[fid].act(tip);
    }
    auto t1 = std::chrono::steady_clock::now();
    ns.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count() / N);
  }
  std::sort(ns.begin(), ns.end());
  std::cout << "nq " << model.nq << " median " << ns[10] << " ns min " << ns[0] << " ns (acc " << acc.transpose() << ")\n";
  // Check against the zero pose: tip at (1.2, 0, 1.405).
  pinocchio::forwardKinematics(model, data, Eigen::VectorXd::Zero(model.nq));
  pinocchio::updateFramePlacement(model, data, fid);
  std::cout << "zero pose tip " << data.oMf[fid].act(tip).transpose() << "\n";
}
