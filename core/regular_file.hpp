#pragma once
// Readers refuse what is not a regular file before opening it: opening a FIFO blocks until a writer comes (forever,
// issue 18), a device such as /dev/zero reads without end, a directory reads as empty. A path that does not exist
// passes, so that each reader keeps its own "cannot open" message.
#include <filesystem>

namespace vmsim::core {

// Throws core::Error "<file>: not a regular file (...)" when `file` exists and is a FIFO, device, socket or directory.
void require_regular_file(const std::filesystem::path& file);

}  // namespace vmsim::core
