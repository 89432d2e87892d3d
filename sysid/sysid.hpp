#pragma once
// Prediction-error identification of an axis as a discrete transfer function from its position command u to its
// encoder position y (the predictive-compensation paper section 2, Table 1):
//   ARX    A(q) y = B(q) q^-nk u + e                     least squares (Householder QR)
//   ARMAX  A(q) y = B(q) q^-nk u + C(q) e                extended least squares, then Gauss-Newton (Levenberg-Marquardt
//                                                        damped) on the one-step prediction error
//   OE     y = B(q)/F(q) q^-nk u + e                     Steiglitz-McBride start, then Levenberg-Marquardt on the
//                                                        simulation error (an OE started from least squares stalls
//                                                        far above the noise floor)
// Orders from the drive's theory (nb = 2, na = 5: the predictive-compensation paper section 2.2, eq. 7) or by BIC over
// ARX fits.
//
// Conditioning. Positions carry large offsets (the axis sits at -150 mm, or runs a ramp) while the dynamics live in
// micrometre differences between u and y. The estimators take deviations from the rest point the trace starts at
// (u - u(0), y - y(0): exact for a linear system that starts at rest, the model then runs from zero state) and scale
// both signals by one common factor (1 / max |u|, which leaves every coefficient unchanged). The regressions are
// solved by column-pivoted QR on equilibrated columns, never by normal equations (cond^2).
#include "drives/discrete_tf.hpp"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

namespace vmsim::sysid {

enum class ModelStructure { Arx, Armax, Oe };
const char* structure_name(ModelStructure s);                         // "arx", "armax", "oe"
std::optional<ModelStructure> parse_structure(const std::string& s);  // nullopt for anything else

struct ModelOrders {
  int na = 5;  // denominator A (ARX, ARMAX) or F (OE)
  int nb = 2;  // numerator B
  int nc = 2;  // ARMAX noise numerator C
  int nk = 1;  // input delay, samples (>= 1)
};

// One experiment, already as deviations from its rest point (see above), sampled every period_s; or several
// experiments one after the other (starts: the first sample of each, beginning with 0; empty: one experiment). The
// estimators never mix samples across an experiment's boundary: regressors, filters and simulations restart from
// rest at each start, and the criteria sum only the rows whose every regressor lies within one experiment.
//
// An experiment that does not start at rest (captures start mid-motion) sets initial_state_estimated: the
// simulation-based criteria (OE's estimation, every structure's validation) then estimate each experiment's initial
// state and a constant output offset by least squares along with the model instead of starting it from rest
// (equation-error ARX and ARMAX use measured past outputs and need no initial state).
struct IdData {
  Eigen::VectorXd u, y;
  double period_s = 1e-3;
  std::vector<Eigen::Index> starts;
  bool initial_state_estimated = false;
  // The value subtracted from y (absolute y = y + y_reference, axis units): for the relative error of the EMPS
  // benchmark (Janot, Gautier & Brunot), which is on absolute positions.
  double y_reference = 0.0;
};
// Experiments appended one after the other (each its own deviations from rest), with their starts.
IdData concatenate(const std::vector<IdData>& experiments);

struct SearchOptions {
  int max_iterations = 200;
  double relative_tolerance = 1e-12;  // stop when the loss falls by less than this fraction in an accepted step
};

struct IdentifiedModel {
  ModelStructure structure = ModelStructure::Arx;
  ModelOrders orders;
  drives::DiscreteTf g;  // G = B/A (ARX, ARMAX) or B/F (OE), with nk and the period
  Eigen::VectorXd c;     // ARMAX: c1 .. c_nc; empty otherwise
  double loss = 0.0;     // the estimation criterion: mean squared prediction error (OE: simulation error), axis units^2
  int iterations = 0;    // Gauss-Newton / Levenberg-Marquardt iterations (0 for ARX)
  bool converged = true;  // the search met its tolerance (ARX: always)
};

// Throws core::Error (no file: the caller names it) for orders the data cannot carry (na < 0, nb < 1, nk < 1, fewer
// samples than 10 x the parameters) or non-finite data.
IdentifiedModel identify_arx(const IdData& data, const ModelOrders& orders);
IdentifiedModel identify_armax(const IdData& data, const ModelOrders& orders, const SearchOptions& options = {});
IdentifiedModel identify_oe(const IdData& data, const ModelOrders& orders, const SearchOptions& options = {});
IdentifiedModel identify(ModelStructure s, const IdData& data, const ModelOrders& orders,
                         const SearchOptions& options = {});

// One-step-ahead prediction errors of the model on data (ARX: A y - B u; ARMAX: (A y - B u) / C; OE: y - B/F u).
Eigen::VectorXd prediction_errors(const IdentifiedModel& m, const IdData& data);

// Order selection by the Bayesian information criterion over ARX fits (cheap, and the estimate ARMAX and OE refine):
// BIC = N ln(V) + d ln(N), V the mean squared one-step error, d = na + nb, for na in [1, max_na], nb in [1, min(na,
// max_nb)], nk in [1, max_nk]. Returns the orders with the smallest BIC (nc = nb).
struct OrderSearch {
  int max_na = 8, max_nb = 4, max_nk = 5;
};
ModelOrders select_orders_bic(const IdData& data, const OrderSearch& search = {});
// The delay for given na, nb: the nk in [1, max_nk] whose ARX fit has the smallest loss.
int select_delay(const IdData& data, int na, int nb, int max_nk = 5);

// Validation on separate data (the predictive-compensation paper section 3, eq. 16-17), the model simulated from zero
// state (or with its initial state and output offset estimated: IdData::initial_state_estimated):
struct Validation {
  double fit_percent = 0.0;  // 100 (1 - |y - yhat| / |y - mean y|)
  double r2 = 0.0;           // 1 - sum (y - yhat)^2 / sum (y - mean y)^2 (eq. 16)
  double mse = 0.0;          // mean (y - yhat)^2, axis units^2 (eq. 17)
  // The same fit on the following error u - y, which the contour error comes from: the position fit of a servo is
  // near 100 % for any model with unit static gain, this one says how well the lag itself is predicted.
  double tracking_fit_percent = 0.0;
  double max_abs_error = 0.0;  // max |y - yhat|, axis units
  // 100 |y - yhat| / |y| on absolute positions (y + IdData::y_reference): the relative error of the EMPS benchmark
  // (Janot, Gautier & Brunot, eq. 11), to compare with its published figures.
  double relative_error_percent = 0.0;
  // Residual whiteness: autocorrelation r(tau) of the one-step prediction errors at lags 1..lags, the portmanteau
  // statistic Q = N sum r^2 against the 99 % quantile of chi^2(lags) (Box-Pierce; Ljung, System Identification,
  // 2nd ed., section 16.6); max |r| and the per-lag 99 % band 2.58/sqrt(N) for the record.
  int lags = 25;
  double max_abs_autocorrelation = 0.0;
  double whiteness_bound = 0.0;  // 2.58 / sqrt(N)
  double portmanteau_q = 0.0;
  double portmanteau_limit = 0.0;  // chi^2(lags) 99 % quantile
  bool white = false;              // Q <= limit
  Eigen::VectorXd simulated;       // yhat
};
// first_sample: the model runs over the whole record (from the rest it starts at) but the figures count only samples
// k >= first_sample (held-out data after an estimation part of the same record).
Validation validate(const IdentifiedModel& m, const IdData& data, int lags = 25, Eigen::Index first_sample = 0);

}  // namespace vmsim::sysid
