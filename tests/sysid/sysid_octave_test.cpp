// vmsim's ARX against GNU Octave's `arx` (octave-control 3.4, ../shared/peers/README.md section 3) on the same data:
// the reference is the peer's own estimate, read back from its printout at 17 significant digits. Octave's arx
// builds B with the one-sample delay included (B = b1 q^-1 + ... + b_nb q^-nb, and nb <= na), i.e. vmsim's nk = 1;
// its 'nk', k adds k MORE samples (vmsim's nk = k + 1). tfdata gives num and den in descending powers of z, leading
// zeros dropped: den = [1 a1 .. a_na 0 ..] (padded by the delay), num = [b1 .. b_nb 0 ..] (padded to den's degree).
// Both regress over the same rows (from max(na, nb) on).
// Two data sets: the peer README's textbook system (A = 1 - 1.5 q^-1 + 0.7 q^-2, B = q^-1 + 0.5 q^-2, PRBS, noise)
// and the predictive-compensation paper's real case, the simulated cascade X axis (Mikron UCP 710) under an inverse
// M-sequence on a ramp with orders nb 2 / na 5 (badly conditioned: y is u delayed by micrometres), for nk = 1 and nk =
// 3 ('nk', 2 in Octave). Skips when octave-cli or its control package is absent.
#include "core/machine.hpp"
#include "drives/cascade_axis.hpp"
#include "drives/discrete_tf.hpp"
#include "sysid/excite.hpp"
#include "drives/simulate.hpp"
#include "sysid/sysid.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

namespace vmsim::sysid {
namespace {

namespace fs = std::filesystem;

int run(const std::string& cmd, std::string* out = nullptr) {
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return -1;
  char buf[4096];
  std::string s;
  while (std::size_t n = std::fread(buf, 1, sizeof buf, p)) s.append(buf, n);
  const int st = pclose(p);
  if (out) *out = s;
  return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

bool octave_with_control() {
  static const int ok = [] {
    std::string out;
    if (run("command -v octave-cli >/dev/null 2>&1") != 0) return 0;
    return run("octave-cli --no-gui --quiet --eval \"pkg load control; disp(exist('arx'))\" 2>/dev/null", &out) == 0 &&
                   out.find('2') != std::string::npos
               ? 1
               : 0;
  }();
  return ok == 1;
}

// Octave's estimate for (u, y) with vmsim's orders: a1..a_na then b1..b_nb.
Eigen::VectorXd octave_arx(const Eigen::VectorXd& u, const Eigen::VectorXd& y, int na, int nb, int nk,
                           const std::string& tag) {
  const fs::path dir = fs::temp_directory_path() / ("vmsim_octave_arx_" + std::to_string(::getpid()) + "_" + tag);
  fs::create_directories(dir);
  {
    std::ofstream f(dir / "data.txt");
    f.precision(17);
    for (Eigen::Index k = 0; k < u.size(); ++k) f << u[k] << ' ' << y[k] << '\n';
  }
  {
    std::ofstream f(dir / "vmsim_arx.m");
    f << "pkg load control\nd = load('data.txt');\ndat = iddata(d(:,2), d(:,1), 1e-3);\n"
      << "sys = arx(dat, 'na', " << na << ", 'nb', " << nb;
    if (nk > 1) f << ", 'nk', " << nk - 1;  // Octave's nk: samples beyond the built-in one
    f << ");\n[num, den] = tfdata(sys); num = num{1}; den = den{1};\n"
      << "printf('%d\\n', numel(den)); printf('%.17g\\n', den); printf('%d\\n', numel(num)); printf('%.17g\\n', "
         "num);\n";
  }
  std::string out;
  const int rc = run("cd '" + dir.string() + "' && octave-cli --no-gui --quiet vmsim_arx.m 2>/dev/null", &out);
  fs::remove_all(dir);
  EXPECT_EQ(rc, 0) << out;
  // The whole den and num as Octave holds them: a1 .. a_na at den(2 .. na + 1), b1 .. b_nb at num(1 .. nb).
  std::istringstream in(out);
  std::vector<double> den, num;
  for (std::vector<double>* v : {&den, &num}) {
    std::size_t count = 0;
    in >> count;
    v->resize(count);
    for (double& c : *v) in >> c;
  }
  Eigen::VectorXd th = Eigen::VectorXd::Zero(na + nb);
  if (!in || den.size() < static_cast<std::size_t>(na + 1) || num.size() < static_cast<std::size_t>(nb)) {
    ADD_FAILURE() << "could not read Octave's coefficients from:\n" << out;
    return th;
  }
  for (int i = 0; i < na; ++i) th[i] = den[static_cast<std::size_t>(i + 1)];
  for (int j = 0; j < nb; ++j) th[na + j] = num[static_cast<std::size_t>(j)];
  return th;
}

void compare(const IdentifiedModel& m, const Eigen::VectorXd& oct, double tol) {
  const int na = m.g.na(), nb = m.g.nb();
  Eigen::VectorXd mine(na + nb);
  mine << m.g.a, m.g.b;
  std::printf("na %d nb %d nk %d: largest |vmsim - Octave| over the coefficients %.3g\n", na, nb, m.g.nk,
              (mine - oct).cwiseAbs().maxCoeff());
  for (int i = 0; i < na; ++i) EXPECT_NEAR(m.g.a[i], oct[i], tol) << "a" << i + 1;
  for (int j = 0; j < nb; ++j) EXPECT_NEAR(m.g.b[j], oct[na + j], tol) << "b" << j + 1;
}

TEST(SysidOctave, ArxEqualsOctaveOnTheTextbookSystem) {
  if (!octave_with_control()) GTEST_SKIP() << "octave-cli with the control package is not installed";
  const int n = 4000;
  const std::vector<int> m = m_sequence(10);
  IdData d;
  d.u.resize(n);
  for (int k = 0; k < n; ++k) d.u[k] = m[static_cast<std::size_t>(k) % m.size()] ? 1.0 : -1.0;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> nd(0.0, 0.05);
  Eigen::VectorXd e(n);
  for (int k = 0; k < n; ++k) e[k] = nd(rng);
  Eigen::VectorXd a0(3), b0(3), one(1);
  a0 << 1.0, -1.5, 0.7;
  b0 << 0.0, 1.0, 0.5;
  one << 1.0;
  d.y = drives::filter_q(b0, a0, d.u) + drives::filter_q(one, a0, e);
  for (int nk : {1, 3}) {
    const IdentifiedModel mine = identify_arx(d, {2, 2, 0, nk});
    compare(mine, octave_arx(d.u, d.y, 2, 2, nk, "textbook" + std::to_string(nk)), 1e-6);
  }
}

TEST(SysidOctave, ArxEqualsOctaveOnTheCascadeAxis) {
  if (!octave_with_control()) GTEST_SKIP() << "octave-cli with the control package is not installed";
  const core::Machine mach = core::load_machine(std::string(VMSIM_SOURCE_DIR) + "/parts/machines/mikron_ucp710.toml");
  const core::MachineAxis& ax = mach.axes[0];
  const double te = 1e-3;
  ExcitationSpec spec;
  spec.switch_samples = switch_samples_for_bandwidth(40.0, te);
  spec.bits = 7;
  spec.amplitude = 0.05;
  spec.velocity = 20.0;
  spec.periods = 2;
  spec.period_s = te;
  const Eigen::VectorXd u = excitation_setpoints(spec);
  drives::CascadeAxis cascade(*ax.drive, te, ax.kind);
  cascade.reset(u[0]);
  const Eigen::VectorXd y = drives::simulate_axis(cascade, u, te, u.size());
  IdData d;
  d.u = u.array() - u[0];
  d.y = y.array() - y[0];
  for (int nk : {1, 3}) {
    const IdentifiedModel mine = identify_arx(d, {5, 2, 0, nk});
    compare(mine, octave_arx(d.u, d.y, 5, 2, nk, "cascade" + std::to_string(nk)), 1e-6);
  }
}

}  // namespace
}  // namespace vmsim::sysid
