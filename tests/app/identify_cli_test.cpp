// vmsim identify-friction end to end: a trace CSV written here from the cascade drive model (Mikron X: Kt 1.5 N m/A,
// 20 mm lead, Coulomb 1.5 N m, viscous 0.005 N m s/rad, J 0.0103 kg m^2), the command run as a user runs it, and
// the TOML it writes read back. Reference: the model's own parameters (within 2 %); the error conventions of
// DESIGN.md (file:line and column named, non-zero exit).
#include "core/machine.hpp"
#include "drives/cascade_axis.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "tests/app/cli_util.hpp"
#include "tests/test_paths.hpp"

using vmsim_test::CliRun;
using vmsim_test::run_vmsim;
using vmsim_test::slurp;
using vmsim_test::TempDir;

namespace fs = std::filesystem;

namespace {

using vmsim::test::kMikronMachine;

// The X drive through +-1, 4, 10, 20 m/min moves (smooth ramps at 2 m/s^2, 0.4 s cruise), sampled every 125 us
// (the velocity-loop period, as a drive's servo trace), current with 0.05 A of Gaussian noise, position to 0.1 um.
vmsim::core::DriveParams write_trace(const fs::path& file) {
  using namespace vmsim;
  const core::Machine m = core::load_machine(kMikronMachine);
  const core::MachineAxis& ax = m.axes[0];
  const double te = 1e-3, pi = 3.14159265358979323846;
  std::vector<double> xd{-150.0};
  double x = xd.back();
  auto run = [&](double duration, auto velocity) {
    const int n = static_cast<int>(std::lround(duration / te));
    for (int k = 1; k <= n; ++k) {
      x += 0.5 * (velocity((k - 1) * te) + velocity(k * te)) * te;
      xd.push_back(x);
    }
  };
  for (double v_m_min : {1.0, -1.0, 4.0, -4.0, 10.0, -10.0, 20.0, -20.0}) {
    const double v = v_m_min * 1000.0 / 60.0, tr = std::max(0.05, pi * std::abs(v) / (2 * 2000.0));
    run(tr, [&](double t) { return v * std::pow(std::sin(pi * t / (2 * tr)), 2); });
    run(0.4, [&](double) { return v; });
    run(tr, [&](double t) { return v * std::pow(std::cos(pi * t / (2 * tr)), 2); });
    run(0.15, [](double) { return 0.0; });
  }
  drives::CascadeAxis axis(*ax.drive, te, ax.kind);
  axis.reset(xd.front());
  std::vector<drives::InnerSample> period(static_cast<std::size_t>(axis.inner_steps()));
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.05);
  std::ofstream out(file, std::ios::binary);
  out << "# simulated Mikron X\nt_s,position_mm,current_A,velocity_setpoint\n";
  double prev = xd.front(), prev_v = 0.0;
  char line[128];
  for (std::size_t k = 0; k < xd.size() + 200; ++k) {
    drives::AxisCommand c;
    c.position = xd[std::min(k, xd.size() - 1)];
    c.velocity = (c.position - prev) / te;
    c.acceleration = (c.velocity - prev_v) / te;
    prev = c.position, prev_v = c.velocity;
    axis.step(c, period.data());
    for (int j = 0; j < axis.inner_steps(); j += 2) {  // every 125 us
      const drives::InnerSample& s = period[static_cast<std::size_t>(j)];
      std::snprintf(line, sizeof line, "%.7f,%.4f,%.5f,%.3f\n", k * te + j * axis.current_period_s(),
                    1e-4 * std::round(s.position / 1e-4), s.current_A + noise(rng), c.velocity);
      out << line;
    }
  }
  return *ax.drive;
}

// key = value lines of a TOML file (numbers and strings; comments stripped).
std::map<std::string, std::string> toml_keys(const std::string& text) {
  std::map<std::string, std::string> keys;
  std::stringstream ss(text);
  std::string l;
  while (std::getline(ss, l)) {
    if (const auto hash = l.find('#'); hash != std::string::npos) l.resize(hash);
    const auto eq = l.find('=');
    if (eq == std::string::npos) continue;
    auto trim = [](std::string s) {
      while (!s.empty() && (s.front() == ' ' || s.front() == '"')) s.erase(s.begin());
      while (!s.empty() && (s.back() == ' ' || s.back() == '"')) s.pop_back();
      return s;
    };
    keys[trim(l.substr(0, eq))] = trim(l.substr(eq + 1));
  }
  return keys;
}

double rel(const std::string& got, double want) { return std::abs(std::stod(got) - want) / want; }

}  // namespace

TEST(IdentifyCli, RecoversTheSimulatedDriveAndWritesItsKeys) {
  TempDir d("vmsim_identify_cli_");
  const fs::path trace = d.path() / "x_trace.csv";
  const vmsim::core::DriveParams p = write_trace(trace);
  for (const std::string& motor :
       std::vector<std::string>{"--torque-constant 1.5 --lead-mm 20", "--machine '" + kMikronMachine + "' --axis X"}) {
    const fs::path out = d.path() / "out";
    fs::remove_all(out);
    const CliRun r =
        run_vmsim("identify-friction '" + trace.string() + "' " + motor + " --out '" + out.string() + "'", d);
    ASSERT_EQ(r.code, 0) << r.err << r.out;
    EXPECT_NE(r.out.find("Coulomb friction"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("ignored columns: velocity_setpoint"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("8 constant-velocity stretches: 4 positive, 4 negative"), std::string::npos) << r.out;
    const auto keys = toml_keys(slurp(out / "drive_identified.toml"));
    ASSERT_TRUE(keys.count("coulomb_friction_Nm")) << slurp(out / "drive_identified.toml");
    EXPECT_LT(rel(keys.at("coulomb_friction_Nm"), p.coulomb_Nm), 0.02);
    EXPECT_LT(rel(keys.at("viscous_friction_Nm_s_per_rad"), p.viscous_Nm_s_per_rad), 0.02);
    EXPECT_LT(rel(keys.at("inertia_kg_m2"), p.inertia_kg_m2), 0.02);
    EXPECT_LT(rel(keys.at("torque_constant_Nm_per_A"), 1.5), 1e-9);
    EXPECT_LT(rel(keys.at("screw_lead_mm"), 20.0), 1e-9);
    // X carries no load: the machine file says so, and without it the fitted offset is not significant.
    EXPECT_EQ(keys.at("gravity"), "none");
    EXPECT_EQ(keys.count("gravity_torque_Nm"), 0u);
    // The fit: one row per stretch, velocity in mm/s, measured and fitted currents within the noise.
    std::stringstream csv(slurp(out / "friction_fit.csv"));
    std::string l;
    std::getline(csv, l);
    EXPECT_EQ(l, "velocity_mm_per_s,measured_mean_current_A,fitted_current_A,samples,t_start_s,t_end_s");
    int rows = 0;
    while (std::getline(csv, l)) {
      std::stringstream ls(l);
      std::string a, b, c;
      std::getline(ls, a, ',');
      std::getline(ls, b, ',');
      std::getline(ls, c, ',');
      EXPECT_NEAR(std::stod(b), std::stod(c), 0.01) << l;
      ++rows;
    }
    EXPECT_EQ(rows, 8);
    EXPECT_TRUE(fs::exists(out / "report.json"));
    vmsim_test::expect_report_html(out, "--pictures no");
  }
}

TEST(IdentifyCli, ErrorsNameFileLineAndColumn) {
  TempDir d("vmsim_identify_cli_");
  const fs::path bad = d.path() / "bad.csv";
  std::ofstream(bad) << "t_s,position_mm,current_A\n0.000,0,0.1\n0.001,0.01,0.1x\n";
  CliRun r = run_vmsim("identify-friction '" + bad.string() + "' --torque-constant 1.5 --lead-mm 20", d);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("bad.csv:3: column 3 'current_A': '0.1x' is not a finite number"), std::string::npos) << r.err;

  const fs::path trace = d.path() / "x_trace.csv";
  write_trace(trace);
  r = run_vmsim("identify-friction '" + trace.string() + "' --lead-mm 20", d);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("torque constant is needed"), std::string::npos) << r.err;
  r = run_vmsim("identify-friction '" + trace.string() + "' --machine '" + kMikronMachine + "' --axis Q", d);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("no axis 'Q' (the machine has X, Y, Z, A, C)"), std::string::npos) << r.err;
  r = run_vmsim("identify-friction '" + trace.string() + "' --machine '" + kMikronMachine + "' --axis A", d);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("axis A is rotary but the trace"), std::string::npos) << r.err;
  r = run_vmsim("identify-friction '" + trace.string() + "' --torque-constant 1.5 --gear-deg-per-rev 4", d);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--gear-deg-per-rev is for a rotary axis"), std::string::npos) << r.err;
  r = run_vmsim("identify-friction '" + trace.string() + "' --torque-constant 1.5 --lead-mm 20 --gear-deg-per-rev 4",
                d);
  EXPECT_NE(r.code, 0);  // CLI11: the two exclude each other
}
