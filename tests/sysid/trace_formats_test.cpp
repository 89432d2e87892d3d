// The servo traces users bring (sysid/trace_formats), read from the real files of ../shared/data/real/traces (see
// its README.md; skipped with a message when the folder is absent):
// - LinuxCNC halscope logs of a mill's X axis (a LinuxCNC retrofit, public repository): the sampling period and the
//   sample count are checked against each file's own header and line count (counted here on the raw text, not
//   through the reader), the first and last samples against the raw text, and the move against what the data's
//   README says the captures are: the same 40 mm move at 65 mm/s and 1000 mm/s^2.
// - The EMPS benchmark's MATLAB v5 files (Janot, Gautier & Brunot, "Data Set and Reference Models of EMPS",
//   Workshop on Nonlinear System Identification Benchmarks 2019): 24 841 samples at 1 kHz over 24.84 s, the gains
//   kp = 160.18 1/s, kv = 243.45 V/(m/s) and the drive gain gtau = 35.15 N/V of the benchmark's description.
// - The readers' rules (jitter accepted or resampled, missing pins and variables named with those present) on small
//   files written here, against analytic values.
#include "sysid/trace_formats.hpp"

#include "core/error.hpp"

#include <gtest/gtest.h>
#include <matio.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace vmsim::sysid {
namespace {

namespace fs = std::filesystem;

fs::path real_traces_dir() { return fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "traces"; }

#define REQUIRE_REAL(path) \
  if (!fs::exists(path)) GTEST_SKIP() << (path).string() << " is absent: the real traces of ../shared are not here"

fs::path trace_temp(const std::string& name) {
  return fs::temp_directory_path() / ("vmsim_tf_" + std::to_string(::getpid()) + "_" + name);
}

std::string trace_error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const core::Error& e) {
    return e.what();
  }
  return "no error";
}

// The raw text of a halscope log: its header's period, its non-blank lines after the header, and the value of a
// pin on a line, found by plain string search (independently of the reader).
struct RawLog {
  long long period_ns = 0;
  std::vector<std::string> lines;
};
RawLog raw_log(const fs::path& p) {
  std::ifstream in(p);
  RawLog r;
  std::string line;
  std::getline(in, line);
  std::sscanf(line.c_str(), "Sampling period is %lld", &r.period_ns);
  while (std::getline(in, line))
    if (line.find_first_not_of(" \t\r") != std::string::npos) r.lines.push_back(line);
  return r;
}
double raw_value(const std::string& line, const std::string& pin) {
  const auto at = line.find(pin + " ");
  return at == std::string::npos ? NAN : std::stod(line.substr(at + pin.size() + 1));
}

TEST(HalscopeLog, RealCapturesMatchTheirHeaderAndLineCount) {
  REQUIRE_REAL(real_traces_dir() / "linuxcnc_halscope");
  for (const char* name : {"halscope.log", "halscope2.log", "halscope3.log", "halscope4.log"}) {
    SCOPED_TRACE(name);
    const fs::path p = real_traces_dir() / "linuxcnc_halscope" / name;
    const RawLog raw = raw_log(p);
    ASSERT_EQ(raw.period_ns, 1000000);
    const std::string cmd = "joint.0.motor-pos-cmd", enc = "hm2_7i76e.0.encoder.02.position";
    // The last line is halscope's all-zero line, not a sample.
    ASSERT_EQ(raw_value(raw.lines.back(), cmd), 0.0);
    ASSERT_EQ(raw_value(raw.lines.back(), enc), 0.0);
    const std::size_t samples = raw.lines.size() - 1;

    const HalscopeLog log = read_halscope_log(p);
    EXPECT_DOUBLE_EQ(log.period_s, 1e-3);
    EXPECT_TRUE(log.dropped_zero_line);
    EXPECT_EQ(log.pins, (std::vector<std::string>{"joint.0.f-error", enc, "joint.0.vel-cmd",
                                                  "hm2_7i76e.0.encoder.02.velocity", cmd, "joint.0.f-error-lim"}));
    ASSERT_EQ(log.values.front().size(), samples);

    // Defaults: joint 0 is axis X, its encoder the log's one encoder position pin.
    const PositionTrace t = read_position_trace(p);
    ASSERT_EQ(t.axes, std::vector<std::string>{"X"});
    ASSERT_EQ(static_cast<std::size_t>(t.t_s.size()), samples);
    EXPECT_DOUBLE_EQ(t.period_s, 1e-3);
    EXPECT_EQ(t.max_jitter_s < 1e-12, true);
    EXPECT_FALSE(t.resampled);
    EXPECT_EQ(t.command(0, 0), raw_value(raw.lines.front(), cmd));
    EXPECT_EQ(t.actual(0, 0), raw_value(raw.lines.front(), enc));
    EXPECT_EQ(t.command(t.t_s.size() - 1, 0), raw_value(raw.lines[samples - 1], cmd));
    EXPECT_EQ(t.actual(t.t_s.size() - 1, 0), raw_value(raw.lines[samples - 1], enc));

    // The move the README describes: 65 mm/s and 1000 mm/s^2 on the command (central differences; the command is
    // LinuxCNC's trajectory planner's, sampled every 1 ms).
    const Eigen::VectorXd c = t.command.col(0);
    double vmax = 0.0, amax = 0.0;
    for (Eigen::Index k = 1; k + 1 < c.size(); ++k) {
      vmax = std::max(vmax, std::abs(c[k + 1] - c[k - 1]) / 2e-3);
      amax = std::max(amax, std::abs(c[k + 1] - 2 * c[k] + c[k - 1]) / 1e-6);
    }
    EXPECT_NEAR(vmax, 65.0, 0.1);
    EXPECT_NEAR(amax, 1000.0, 20.0);

    // --channel: the same pins named explicitly give the same trace; the motor's own feedback pin is absent.
    TraceChannels ch;
    ch.pins = {parse_pin_pair("X=" + cmd + "," + enc)};
    EXPECT_EQ(read_position_trace(p, ch).actual, t.actual);
    ch.pins = {parse_pin_pair("X=" + cmd + ",joint.0.motor-pos-fb")};
    const std::string e = trace_error_of([&] { read_position_trace(p, ch); });
    EXPECT_NE(e.find("no pin 'joint.0.motor-pos-fb' (pins present: joint.0.f-error, " + enc), std::string::npos) << e;
  }
}

TEST(MatTrace, EmpsFilesMatchTheBenchmarkDescription) {
  REQUIRE_REAL(real_traces_dir() / "emps");
  for (const char* name : {"DATA_EMPS.mat", "DATA_EMPS_PULSES.mat"}) {
    SCOPED_TRACE(name);
    const fs::path p = real_traces_dir() / "emps" / name;
    EXPECT_EQ(detect_trace_format(p), TraceFormat::Mat);
    EXPECT_NEAR(read_mat_vector(p, "gtau").at(0), 35.15, 0.005);
    EXPECT_EQ(read_mat_vector(p, "kp").at(0), 160.18);
    EXPECT_EQ(read_mat_vector(p, "kv").at(0), 243.45);
    TraceChannels ch;
    ch.variables = parse_mat_variables("t=t,command=qg,actual=qm");
    ch.unit = "m";
    const PositionTrace t = read_position_trace(p, ch);
    ASSERT_EQ(t.t_s.size(), 24841);  // 24.84 s at 1 kHz, both ends included
    EXPECT_NEAR(t.period_s, 1e-3, 1e-12);
    // The time vector is stored with ~1e-5 s resolution steps (0.001000024 s): jitter well within the tolerance.
    EXPECT_GT(t.max_jitter_s, 0.0);
    EXPECT_LT(t.max_jitter_s, 1e-4 * t.period_s);
    EXPECT_FALSE(t.resampled);
    EXPECT_EQ(t.axes, std::vector<std::string>{"X"});
    // Positions in m in the file, mm here; both captures start mid-motion (the reference already at 0.108 mm).
    EXPECT_NEAR(t.command(0, 0), 0.10782208, 1e-8);
    EXPECT_DOUBLE_EQ(t.actual(100, 0), 1000.0 * read_mat_vector(p, "qm").at(100));

    ch.variables = parse_mat_variables("t=t,command=qg,actual=q_measured");
    const std::string e = trace_error_of([&] { read_position_trace(p, ch); });
    EXPECT_NE(e.find("no variable 'q_measured' (the file has: "), std::string::npos) << e;
    EXPECT_NE(e.find("qm"), std::string::npos) << e;
  }
}

TEST(MatTrace, AxisTraceForFrictionFromEmps) {
  REQUIRE_REAL(real_traces_dir() / "emps");
  const fs::path p = real_traces_dir() / "emps" / "DATA_EMPS.mat";
  TraceChannels ch;
  ch.variables = parse_mat_variables("t=t,position=qm,control=vir");
  ch.unit = "m";
  const AxisTrace t = read_axis_trace(p, ch);
  ASSERT_EQ(t.t_s.size(), 24841);
  EXPECT_FALSE(t.rotary);
  EXPECT_NEAR(t.position[0], 7.45e-3, 1e-4);
  EXPECT_NEAR(t.current_A[0], 2.538628089, 1e-8);
  ch.variables = parse_mat_variables("t=t,command=qg,control=vir");
  const std::string e = trace_error_of([&] { read_axis_trace(p, ch); });
  EXPECT_NE(e.find("--mat: 'command' is not a role here"), std::string::npos) << e;
}

// .mat files written here by libmatio itself, v5 and v7.3 (HDF5), in single precision: the reader takes the
// variables by name, converts float to double and m to mm, and finds the format by the file's header.
TEST(MatTrace, V5AndV73FilesWrittenByLibmatio) {
  for (const mat_ft version : {MAT_FT_MAT5, MAT_FT_MAT73}) {
    const fs::path p = trace_temp(version == MAT_FT_MAT5 ? "v5.mat" : "v73.mat");
    mat_t* m = Mat_CreateVer(p.string().c_str(), nullptr, version);
    if (!m) GTEST_SKIP() << "this libmatio cannot write " << (version == MAT_FT_MAT73 ? "v7.3 (no HDF5)" : "v5");
    std::vector<float> t(50), c(50), a(50);
    for (int k = 0; k < 50; ++k) t[k] = 0.002f * k, c[k] = 0.001f * k, a[k] = 0.001f * k - 0.0005f;
    std::size_t dims[2] = {50, 1};
    for (const auto& [name, v] : {std::pair{"time", &t}, std::pair{"ref", &c}, std::pair{"pos", &a}}) {
      matvar_t* var = Mat_VarCreate(name, MAT_C_SINGLE, MAT_T_SINGLE, 2, dims, v->data(), 0);
      ASSERT_EQ(Mat_VarWrite(m, var, MAT_COMPRESSION_NONE), 0);
      Mat_VarFree(var);
    }
    Mat_Close(m);
    SCOPED_TRACE(p.string());
    EXPECT_EQ(detect_trace_format(p), TraceFormat::Mat);
    TraceChannels ch;
    ch.variables = parse_mat_variables("t=time,command=ref,actual=pos,axis=Y");
    ch.unit = "m";
    const PositionTrace tr = read_position_trace(p, ch);
    fs::remove(p);
    ASSERT_EQ(tr.t_s.size(), 50);
    EXPECT_EQ(tr.axes, std::vector<std::string>{"Y"});
    EXPECT_NEAR(tr.period_s, 0.002, 1e-9);
    EXPECT_FALSE(tr.resampled);  // float time stamps: a jitter of about 1e-9 s
    EXPECT_NEAR(tr.command(10, 0), 10.0, 1e-5);
    EXPECT_NEAR(tr.actual(10, 0), 9.5, 1e-5);
  }
}

// A small CSV trace whose time stamps step by period (1 + jitter (-1)^k): linear signals, so a resampling by linear
// interpolation must give them exactly at the mean period.
fs::path jittery_trace(double jitter) {
  const fs::path p = trace_temp("jitter.csv");
  std::ofstream out(p);
  out << "t_s,X_command_mm,X_actual_mm\n";
  double t = 0.0;
  for (int k = 0; k < 101; ++k) {
    out << std::setprecision(17) << t << "," << 2.0 * t + 1.0 << "," << -3.0 * t << "\n";
    t += 1e-3 * (1.0 + (k % 2 ? -jitter : jitter));
  }
  return p;
}

TEST(TraceSampling, SmallJitterIsAcceptedLargeJitterIsResampled) {
  {
    const fs::path p = jittery_trace(0.005);  // 0.5 % of the period: within kJitterTolerance
    const PositionTrace t = read_position_trace(p);
    fs::remove(p);
    EXPECT_FALSE(t.resampled);
    EXPECT_NEAR(t.max_jitter_s, 0.005e-3, 1e-12);
    EXPECT_NEAR(t.period_s, 1e-3, 1e-12);
    EXPECT_NEAR(t.t_s[1], 1.005e-3, 1e-15);  // the stamps themselves are kept
  }
  {
    const fs::path p = jittery_trace(0.2);  // 20 %: resampled onto the mean period
    const PositionTrace t = read_position_trace(p);
    fs::remove(p);
    EXPECT_TRUE(t.resampled);
    EXPECT_NEAR(t.max_jitter_s, 0.2e-3, 1e-12);
    ASSERT_EQ(t.t_s.size(), 101);
    for (Eigen::Index k = 0; k < t.t_s.size(); ++k) {
      EXPECT_NEAR(t.t_s[k], k * t.period_s, 1e-12);
      EXPECT_NEAR(t.command(k, 0), 2.0 * t.t_s[k] + 1.0, 1e-12);
      EXPECT_NEAR(t.actual(k, 0), -3.0 * t.t_s[k], 1e-12);
    }
  }
}

TEST(TraceFormats, OptionsAreCheckedAndMisuseIsNamed) {
  EXPECT_EQ(parse_pin_pair("Y=joint.1.motor-pos-cmd, joint.1.motor-pos-fb").actual, "joint.1.motor-pos-fb");
  EXPECT_NE(
      trace_error_of([] { parse_pin_pair("X=joint.0.motor-pos-cmd"); }).find("expected AXIS=COMMAND_PIN,ACTUAL_PIN"),
      std::string::npos);
  EXPECT_NE(trace_error_of([] { parse_pin_pair("Q=a,b"); }).find("axis 'Q': expected one of X Y Z A B C"),
            std::string::npos);
  EXPECT_NE(trace_error_of([] { parse_mat_variables("t=t,command"); }).find("item 'command': expected ROLE=VARIABLE"),
            std::string::npos);
  EXPECT_NE(trace_error_of([] { parse_mat_variables("t=t,t=time"); }).find("'t' is given twice"), std::string::npos);
  // A halscope log with an unknown header, and one whose channels change names midway.
  const fs::path p = trace_temp("scope.log");
  std::ofstream(p) << "Sampling period is 1000000 nSec\n\njoint.0.motor-pos-cmd +1.0 joint.0.motor-pos-fb +1.0\n"
                      "joint.0.motor-pos-cmd +1.0 joint.1.motor-pos-fb +1.0\n";
  EXPECT_NE(trace_error_of([&] { read_halscope_log(p); })
                .find(":4: channel 2 is 'joint.1.motor-pos-fb' here but "
                      "'joint.0.motor-pos-fb' on line 3"),
            std::string::npos);
  std::ofstream(p) << "Sampling period is 1000000 nSec\n\njoint.0.motor-pos-cmd +1.0 joint.0.motor-pos-fb +1.0\n"
                      "joint.0.motor-pos-cmd +1.0 joint.0.motor-pos-fb +1.0\n";
  TraceChannels csv_only;
  csv_only.variables = {{"t", "t"}};
  EXPECT_NE(trace_error_of([&] { read_position_trace(p, csv_only); }).find("this trace is not a .mat file"),
            std::string::npos);
  const PositionTrace t = read_position_trace(p);  // joint.0.motor-pos-fb: the default actual pin
  EXPECT_EQ(t.axes, std::vector<std::string>{"X"});
  EXPECT_EQ(t.t_s.size(), 2);
  fs::remove(p);
}

}  // namespace
}  // namespace vmsim::sysid
