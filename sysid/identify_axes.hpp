#pragma once
// `vmsim identify` as a library call: every axis of one or more position traces identified as a discrete transfer
// function from command to encoder position (the predictive-compensation paper sections 2-3): ARX, ARMAX and OE
// fitted on the estimation data, validated on separate data, ranked by the validation MSE as the paper's Table 2,
// the chosen one per axis ready for the axis-model file (sysid/axis_model_file.hpp).
//
// Data. Each trace is one experiment, as deviations from its own rest point (sysid.hpp). A trace starts at rest when
// over its first kRestSamples samples neither the command nor the encoder moves more than kRestTolerance;
// the rest point is then its first sample (command and encoder each). A trace that starts mid-motion (a capture
// started while the axis ran) has no such point: its deviations are taken from the first command for both signals,
// the encoder's less the rest offset (encoder - command at rest: given by the user, else measured on the trace's
// first still stretch of kRestStretchSamples samples, else 0, said so), and the model's initial state and a
// constant output offset are estimated with it (IdData::initial_state_estimated). The validation data are
// a separate trace when one is given; else, with several traces, the last one, held out; else the one trace's
// second half (the model then runs over the whole record and only the second half is counted).
#include "sysid/axis_model_file.hpp"
#include "sysid/position_trace.hpp"
#include "sysid/sysid.hpp"

#include <cstddef>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::sysid {

struct AxesIdentificationOptions {
  std::vector<ModelStructure> structures = {ModelStructure::Arx, ModelStructure::Armax, ModelStructure::Oe};
  // na, nb (and nc for ARMAX) as given; nullopt: by BIC over ARX fits (select_orders_bic), nc from `nc`.
  std::optional<ModelOrders> orders = ModelOrders{};
  int nc = 2;                         // ARMAX noise order when the orders come from BIC
  std::optional<int> delay;           // nk; nullopt: BIC's, or the ARX loss's best over 1..5 for given orders
  std::optional<ModelStructure> use;  // the structure chosen per axis; nullopt: the lowest validation MSE
  std::vector<std::string> axes;      // empty: every axis of the first trace
  int lags = 25;                      // residual autocorrelation lags of the whiteness test
  // Rest offsets (encoder - command at rest, axis units: mm or rad) given by the user, per axis name; used for the
  // traces that do not start at rest.
  std::map<std::string, double> rest_offsets;
};

inline constexpr int kRestSamples = 3;
inline constexpr int kRestStretchSamples = 50;
inline constexpr double kRestTolerance = 1e-3;  // mm, or deg on a rotary axis

// A model whose largest pole magnitude exceeds this is marginal (a time constant above 10 000 samples: over a record
// it cannot be told from an integrator) or, above 1, unstable. Such a model ranks after every stable one, and the
// commands warn when they write one.
inline constexpr double kMarginalPoleMagnitude = 1.0 - 1e-4;
bool is_marginal(const drives::DiscreteTf& g);

enum class ValidationData { SecondHalf, HeldOutTrace, SeparateTrace };

// One axis's estimation and validation data.
struct AxisData {
  std::string name;
  bool rotary = false;  // the trace gave degrees (the data are in rad)
  IdData estimation, validation;
  Eigen::Index first_validation_sample = 0;  // the validation figures count samples from here on
  bool at_rest = true;                       // the first trace starts at rest (see above; each IdData says its own)
  // The first trace's |command - encoder| at its first sample (axis units); at rest, the encoder's offset.
  double first_sample_offset = 0.0;
  // For traces that start mid-motion: the rest offset used (encoder - command at rest, axis units) and where it came
  // from ("--rest-offset", "the still stretch at t = ... s", "none: no still stretch in the trace, 0 assumed").
  double rest_offset = 0.0;
  std::string rest_offset_from;
  bool starts_at_rest() const { return at_rest; }
};

struct IdentificationData {
  std::string source;  // the first trace's file, for messages
  double period_s = 1e-3;
  std::size_t estimation_traces = 1;  // traces the estimation uses (several: separate experiments)
  ValidationData validation = ValidationData::SecondHalf;
  std::vector<std::string> estimation_files;  // the estimation traces' file names (no directory)
  std::vector<AxisData> axes;
};

// Checks and splits the traces. Throws core::Error naming the trace for sampling periods that differ (within 1e-6),
// an axis a trace has no columns for, no trace at all.
IdentificationData prepare_identification(const std::vector<PositionTrace>& traces, const PositionTrace* validation,
                                          const AxesIdentificationOptions& options);

struct ModelResult {
  IdentifiedModel model;
  Validation validation;
  double seconds = 0.0;   // wall time of estimation and validation
  int rank = 0;           // 1: lowest validation MSE (marginal or unstable, or non-finite MSE: last)
  bool marginal = false;  // is_marginal(model.g)
};

struct AxisIdentification {
  std::string name;
  bool rotary = false;
  ModelOrders orders;               // the orders and delay used (for ARMAX, nc; the others ignore it)
  std::vector<ModelResult> models;  // in the order of options.structures
  std::size_t chosen = 0;           // index into models: options.use, else rank 1
};

// Sets each model's rank: by validation MSE, every marginal or unstable model (or non-finite MSE) after the others.
void rank_models(std::vector<ModelResult>& models);

// Orders, delay, every structure fitted and validated, ranked. Throws core::Error naming `source` and the axis
// (and structure) when the data cannot carry the orders.
AxisIdentification identify_axis(const AxisData& data, const std::string& source,
                                 const AxesIdentificationOptions& options);

// The model file's entry for the chosen model of an axis, and the whole file (period, trace names, axes).
IdentifiedAxis chosen_axis(const AxisIdentification& axis);
AxisModelFile axis_model_file(const IdentificationData& data, const std::vector<AxisIdentification>& axes);

struct AxesIdentification {
  IdentificationData data;
  std::vector<AxisIdentification> axes;
  AxisModelFile file;
};
// prepare_identification, identify_axis for each axis, axis_model_file.
AxesIdentification identify_axes(const std::vector<PositionTrace>& traces, const PositionTrace* validation,
                                 const AxesIdentificationOptions& options);

}  // namespace vmsim::sysid
