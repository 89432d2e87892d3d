#pragma once
// Paths most test suites use, defined once: test files compile in batches (unity builds), where file-local copies of
// the same name would clash.
#include <filesystem>
#include <string>

namespace vmsim::test {

inline const std::string kSourceDir = VMSIM_SOURCE_DIR;       // the repository
inline const std::string kPartsDir = kSourceDir + "/parts/";  // with its trailing slash
inline const std::filesystem::path kPartsPath = std::filesystem::path(kSourceDir) / "parts";
inline const std::string kMikronMachine = kSourceDir + "/parts/machines/mikron_ucp710.toml";  // the one machine file

}  // namespace vmsim::test
