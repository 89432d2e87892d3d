#include "app/report.hpp"

#include "render/report_html.hpp"

namespace vmsim::app {

// One writer for the CLI and the Python module (render/report_html.hpp).
void write_report(const std::filesystem::path& file, const nlohmann::json& report) { render::write_report(file, report); }

}  // namespace vmsim::app
