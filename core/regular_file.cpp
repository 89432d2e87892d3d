#include "core/regular_file.hpp"

#include "core/error.hpp"

namespace vmsim::core {

void require_regular_file(const std::filesystem::path& file) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(file, ec);
  if (ec || !std::filesystem::exists(st) || std::filesystem::is_regular_file(st)) return;
  const char* kind = std::filesystem::is_directory(st) ? "a directory"
                     : std::filesystem::is_fifo(st)    ? "a FIFO (named pipe), which would block the reader"
                     : std::filesystem::is_character_file(st) || std::filesystem::is_block_file(st)
                         ? "a device, which could be read without end"
                         : "not a regular file";
  throw Error(
      located(file.string(), 0, std::string("not a regular file: it is ") + kind + "; give the path of a file"));
}

}  // namespace vmsim::core
