// Canonical calls as text, formatted like LinuxCNC's standalone canon (saicanon.cc) prints them.
#include "core/error.hpp"
#include "program/gcode_interp.hpp"

#include <charconv>
#include <cstdarg>
#include <cstdio>

namespace vmsim::program::gcode {

const std::string CanonWriter::kNoN = "N.....";

void CanonWriter::print(const char* format, ...) {
  // printf formatting on purpose: "%.4f" rounds, and prints -0.0000, exactly as `rs274` does.
  char small[256];
  va_list args;
  va_start(args, format);
  va_list copy;
  va_copy(copy, args);
  const int n = std::vsnprintf(small, sizeof small, format, args);
  va_end(args);
  std::string text;
  if (n < 0) {
    va_end(copy);
    throw core::Error("internal error: cannot format a canonical call");
  }
  if (static_cast<std::size_t>(n) < sizeof small) {
    text.assign(small, static_cast<std::size_t>(n));
  } else {  // huge values (e.g. F1e300) print hundreds of digits
    text.resize(static_cast<std::size_t>(n) + 1);
    std::vsnprintf(text.data(), text.size(), format, copy);
    text.resize(static_cast<std::size_t>(n));
  }
  va_end(copy);
  push(std::move(text));
}

void CanonWriter::push(std::string text) {
  if (calls_.size() >= max_calls_)
    throw core::Error(core::located(
        file_, line_, "more than " + std::to_string(max_calls_) + " canonical calls: possible endless loop"));
  calls_.push_back(CanonCall{line_, *n_word_, std::move(text)});
}

namespace {
void append_fixed4(std::string& s, double v) {
  char buf[400];  // %.4f of 1.8e308 has 309 integer digits
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, 4);
  s.append(buf, r.ptr);
}
}  // namespace

void CanonWriter::axes_call(const char* name, const double* values, int n) {
  std::string text;
  text.reserve(16 + 12 * static_cast<std::size_t>(n));
  text += name;
  text += '(';
  for (int i = 0; i < n; ++i) {
    if (i) text += ", ";
    append_fixed4(text, values[i]);
  }
  text += ')';
  push(std::move(text));
}

void CanonWriter::arc_call(const double* plane4, int rotation, const double* rest4) {
  std::string text;
  text.reserve(112);
  text += "ARC_FEED(";
  for (int i = 0; i < 4; ++i) {
    append_fixed4(text, plane4[i]);
    text += ", ";
  }
  text += std::to_string(rotation);
  for (int i = 0; i < 4; ++i) {
    text += ", ";
    append_fixed4(text, rest4[i]);
  }
  text += ')';
  push(std::move(text));
}

}  // namespace vmsim::program::gcode

namespace vmsim::program {

std::string format_canon_line(int number, const CanonCall& call) {
  char head[32];
  std::snprintf(head, sizeof head, "%5d ", number);
  std::string s = head;
  s += call.n_word;
  // rs274 pads the N column to 7 characters ("N..... ", "N30    "); longer N words run into the call.
  if (call.n_word.size() < 7) s.append(7 - call.n_word.size(), ' ');
  s += call.text;
  return s;
}

}  // namespace vmsim::program
