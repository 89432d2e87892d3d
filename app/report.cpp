#include "app/report.hpp"

#include "core/atomic_file.hpp"

namespace vmsim::app {

void write_report(const std::filesystem::path& file, const nlohmann::json& report) {
  core::write_file_atomic(file, report.dump(2) + "\n");
}

}  // namespace vmsim::app
