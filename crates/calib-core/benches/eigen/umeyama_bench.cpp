// Eigen reference for `cargo bench -p calib-core --bench calib -- rigid` (id "rigid_fit_fast n=4"):
// Eigen::umeyama(src, dst, false) (rigid, no scaling) on the same 4 point pairs as that bench
// (`data(4, 1, false)` in benches/calib.rs: ChaCha8 seed 1, 0.5 mm noise; the values below are
// its exact doubles), src = p_b2, dst = p_b1, so the result is b1_from_b2. Fixed-size 3×4
// matrices. Protocol as crates/kinematics/benches/pinocchio/fk_bench.cpp: 21 runs of 1 000 000
// calls, median and min per call. Build and run: see BENCHMARKS.md, section calib-core.

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <iostream>
#include <vector>

int main() {
  Eigen::Matrix<double, 3, 4> src, dst;
  // p_b1 (dst) and p_b2 (src), columns = points, m.
  const double p_b1[4][3] = {{-5.434913617921054e-1, 1.1121941955348233e0, 7.658256768464812e-1},
                             {-5.228788286136598e-1, 1.550276566740731e0, 9.031446233454717e-1},
                             {-3.946651295445339e-1, 1.1283244222004911e0, 1.0995809782343415e0},
                             {2.5616742666026754e-1, 1.2283498598223848e0, 7.421646621031498e-1}};
  const double p_b2[4][3] = {{-1.5602293813624324e-1, -6.71386065712349e-1, 7.158722171218258e-1},
                             {-4.4908067122592005e-1, -3.4609505391401996e-1, 8.527322684173304e-1},
                             {-6.2258922868934974e-2, -5.557556857503798e-1, 1.049737294123071e0},
                             {3.3059851533689866e-1, -2.678854985999668e-2, 6.926509645604494e-1}};
  for (int k = 0; k < 4; ++k)
    for (int r = 0; r < 3; ++r) {
      dst(r, k) = p_b1[k][r];
      src(r, k) = p_b2[k][r];
    }
  Eigen::Matrix4d acc = Eigen::Matrix4d::Zero();
  std::vector<double> ns;
  const int N = 1000000;
  for (int rep = 0; rep < 21; ++rep) {
    auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < N; ++i) {
      // Make the inputs opaque to the optimiser each call (like criterion's black_box).
      asm volatile("" : : "r"(src.data()), "r"(dst.data()) : "memory");
      acc += Eigen::umeyama(src, dst, false);
    }
    auto t1 = std::chrono::steady_clock::now();
    ns.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count() / N);
  }
  std::sort(ns.begin(), ns.end());
  Eigen::Matrix4d b1_from_b2 = Eigen::umeyama(src, dst, false);
  std::cout << "eigen " << EIGEN_WORLD_VERSION << "." << EIGEN_MAJOR_VERSION << "." << EIGEN_MINOR_VERSION
            << " umeyama n=4: median " << ns[10] << " ns min " << ns[0] << " ns (acc " << acc(0, 0) << ")\n";
  std::cout.precision(17);
  std::cout << "b1_from_b2 =\n" << b1_from_b2 << "\n";
}
