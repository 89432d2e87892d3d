#include "app/report.hpp"

#include "core/atomic_file.hpp"
#include "render/report_html.hpp"

namespace vmsim::app {

void write_report(const std::filesystem::path& file, const nlohmann::json& report) {
  core::write_file_atomic(file, report.dump(2) + "\n");
  // Its page for a person, beside it, from the same object (render/report_html.hpp).
  if (file.filename() == "report.json") render::write_report_html(file.parent_path(), report);
}

}  // namespace vmsim::app
