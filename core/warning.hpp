#pragma once
// A finding about a run that does not stop it: what report.json lists under "warnings" and what decides its
// "verdict" (README, "What you can rely on"). Checks live in the libraries (drives/, sim/); the CLI prints them.
#include <string>
#include <vector>

namespace vmsim::core {

struct Warning {
  // Invalid: the result cannot mean what it claims (e.g. an axis that never followed its setpoints).
  enum class Severity { Warning, Invalid };
  std::string code;     // stable identifier, e.g. "current_saturation"
  std::string subject;  // the axis or the job key it concerns
  std::string message;  // what was found and what to change
  Severity severity = Severity::Warning;
};

using Warnings = std::vector<Warning>;

// "ok" without warnings, "invalid" when any is Invalid, else "warnings".
inline const char* verdict(const Warnings& w) {
  bool invalid = false;
  for (const Warning& x : w) invalid = invalid || x.severity == Warning::Severity::Invalid;
  return invalid ? "invalid" : w.empty() ? "ok" : "warnings";
}

}  // namespace vmsim::core
