// Kinematic transforms per pose: forward (axes -> tool tip and axis, run for every sample of a five-axis job) and
// inverse (pose -> axes near the previous ones, run for every CL point and blend sample), on the Mikron UCP 710's
// A/C table-table chain and LinuxCNC's xyzac-trt. Poses: random reachable axis positions (fixed seed), so the
// inverse is asked for poses it can reach. Figures: bench/README.md.
#include "motion/kinematics.hpp"
#include "core/machine.hpp"

#include <benchmark/benchmark.h>

#include <filesystem>
#include <numbers>
#include <random>
#include <vector>

namespace {

using namespace vmsim::core;
using namespace vmsim::motion;

const std::filesystem::path kSource = VMSIM_SOURCE_DIR;
constexpr double kDeg = std::numbers::pi / 180.0;

// 4096 axis vectors in machine-file order (X Y Z A C): linear axes within +-100 mm, A within [-60, 0] deg (inside
// both machines' travels), C anywhere in one turn.
std::vector<Eigen::VectorXd> random_axes(const Machine& m) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> lin(-100.0, 100.0), a(-60.0 * kDeg, 0.0), c(-180.0 * kDeg, 180.0 * kDeg);
  std::vector<Eigen::VectorXd> out(4096, Eigen::VectorXd(static_cast<Eigen::Index>(m.axes.size())));
  for (auto& q : out) q << lin(rng), lin(rng), lin(rng), a(rng), c(rng);
  return out;
}

void forward(benchmark::State& state, const char* machine_file) {
  const Machine m = load_machine(kSource / "parts/machines" / machine_file);
  const auto kin = make_kinematics(m);
  const auto q = random_axes(m);
  std::size_t i = 0;
  for (auto _ : state) {
    ToolPose p = kin->forward(q[i], 50.0);
    benchmark::DoNotOptimize(p);
    i = (i + 1) & 4095;
  }
  state.counters["poses/s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

void inverse(benchmark::State& state, const char* machine_file) {
  const Machine m = load_machine(kSource / "parts/machines" / machine_file);
  const auto kin = make_kinematics(m);
  const auto q = random_axes(m);
  std::vector<ToolPose> poses;
  for (const auto& qi : q) poses.push_back(kin->forward(qi, 50.0));
  // `near` a little off the true axes, as the previous sample of a path is.
  std::vector<Eigen::VectorXd> near = q;
  for (auto& n : near) n.tail(2).array() += 0.01;
  std::size_t i = 0;
  for (auto _ : state) {
    Eigen::VectorXd a = kin->inverse(poses[i], 50.0, near[i]);
    benchmark::DoNotOptimize(a.data());
    i = (i + 1) & 4095;
  }
  state.counters["poses/s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

BENCHMARK_CAPTURE(forward, mikron_ucp710, "mikron_ucp710.toml");
BENCHMARK_CAPTURE(forward, xyzac_trt, "xyzac_trt.toml");
BENCHMARK_CAPTURE(inverse, mikron_ucp710, "mikron_ucp710.toml");
BENCHMARK_CAPTURE(inverse, xyzac_trt, "xyzac_trt.toml");

}  // namespace
