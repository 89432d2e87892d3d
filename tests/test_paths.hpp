#pragma once
// Paths most test suites use, defined once: test files compile in batches (unity builds), where file-local copies of
// the same name would clash.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace vmsim::test {

inline const std::string kSourceDir = VMSIM_SOURCE_DIR;       // the repository
inline const std::string kPartsDir = kSourceDir + "/parts/";  // with its trailing slash
inline const std::filesystem::path kPartsPath = std::filesystem::path(kSourceDir) / "parts";
inline const std::string kMikronMachine = kSourceDir + "/parts/machines/mikron_ucp710.toml";  // the one machine file

// A directory of the running test's own, $TMPDIR/<group>/<Suite.Test>, made if absent: parallel test processes never
// share one.
inline std::filesystem::path test_scratch_dir(const std::string& group) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / group /
                                    (std::string(info->test_suite_name()) + "." + info->name());
  std::filesystem::create_directories(dir);
  return dir;
}

// `text` written to the file `name` in test_scratch_dir(group); its path.
inline std::filesystem::path write_test_file(const std::string& group, const std::string& name,
                                             const std::string& text) {
  const std::filesystem::path p = test_scratch_dir(group) / name;
  std::ofstream(p, std::ios::binary) << text;
  return p;
}

}  // namespace vmsim::test
