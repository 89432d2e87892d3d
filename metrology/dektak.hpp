#pragma once
// Bruker Dektak stylus profiler CSV exports: sections of "key,value" lines ("Scan Parameters", "Analytical
// Results", ...), then "Scan Data", a header row naming the columns with their units ("Lateral um,Raw
// Micrometer"), and one "x,z" row per sample. The text is latin-1 (the header's micro sign is the byte 0xB5) with
// CR CR LF line ends. The lateral values are printed rounded (to 0.1 um in dektak-1.csv, while the stylus samples
// every 0.15625 um), so their differences are not constant: when every value lies within its printed rounding of
// a uniform grid (least-squares x0 and spacing; 0.75 of the last printed digit, the fit's own uncertainty
// included), the grid is taken; otherwise the heights are resampled linearly onto a uniform grid of the mean
// spacing, and the note says so.
#include "metrology/profile.hpp"

#include <filesystem>
#include <string>
#include <string_view>

namespace vmsim::metrology {

struct DektakData {
  LineScan profile;
  std::string note;
};

// True when the start of a text file looks like a Dektak export (a "Lateral ..." column header after "Scan Data",
// or the "Scan Parameters" section it opens with).
bool looks_like_dektak(std::string_view head);

// Throws core::Error naming the file, the line, and what was expected.
DektakData read_dektak_csv(std::string_view text, const std::string& name);
DektakData read_dektak_csv(const std::filesystem::path& file);

}  // namespace vmsim::metrology
