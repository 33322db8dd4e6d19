#include "kinegen/codegen/analysis.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <kinegen/motion.hpp>
#include <kinegen/solver.hpp>
#include <kinegen/sparse_solver.hpp>
#include <limits>
#include <sstream>

namespace kinegen::codegen {

namespace {

// Estimates (condition numbers, step sizes) read better with three digits than seventeen.
std::string format_estimate(double value) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", value);
  return buf;
}

using Solver = BasicSolver<ProgramSystem>;
using LargeSolver = SparseSolver<ProgramSystem>;

// The sparse path names the constraints behind a singular Phi_q (a dense SVD) only up to this
// many coordinates: the diagnosis runs only on failure, but costs O(nq^2) memory and O(nq^3)
// time (JacobiSVD: about 6 s at nq = 600).
constexpr int kMaxDiagnosedNq = 400;

std::string time_text(double t) { return "t = " + format_number(t); }

// Phi_q with rows equilibrated and columns multiplied by their coordinate's scale, as the
// solver sees it: its singular values compare like with like (metres and radians).
Eigen::MatrixXd scaled_jacobian(const CompiledModel& model, const Eigen::MatrixXd& jac) {
  Eigen::MatrixXd s = jac;
  for (int k = 0; k < s.cols(); ++k) s.col(k) *= model.symbolic().coordinate_scales[k];
  for (int r = 0; r < s.rows(); ++r) {
    const double n = s.row(r).cwiseAbs().maxCoeff();
    if (n > 0) s.row(r) /= n;
  }
  return s;
}

Eigen::MatrixXd jacobian_at(const CompiledModel& model, const Eigen::VectorXd& q, double t) {
  ModelEvaluator<double> eval(model);
  Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(model.nc(), model.nq());
  eval.jacobian(q.data(), t, jac);
  return jac;
}

// The constraints behind a (near-)singular Phi_q: rows that carry weight in the left singular
// vectors of its smallest singular values (those within a factor 10 of the smallest, and
// always the smallest), with the scaled condition estimate.
std::string singular_rows(const CompiledModel& model, const Eigen::MatrixXd& jac) {
  if (!jac.allFinite()) return "";
  const Eigen::MatrixXd s = scaled_jacobian(model, jac);
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(s, Eigen::ComputeFullU);
  const Eigen::VectorXd sv = svd.singularValues();
  const double s_max = sv.size() ? sv(0) : 0.0;
  // With nc > nq the last nc - nq left singular vectors span the redundancy, not the
  // singularity: look at the nq-th singular value.
  const int k_min = static_cast<int>(std::min(s.rows(), s.cols())) - 1;
  const double s_min = k_min >= 0 ? sv(k_min) : 0.0;
  Eigen::VectorXd weight = Eigen::VectorXd::Zero(s.rows());
  for (int k = 0; k <= k_min; ++k)
    if (k == k_min || sv(k) <= 10 * s_min + 1e-14 * s_max)
      weight = weight.cwiseMax(svd.matrixU().col(k).cwiseAbs());
  std::string rows;
  for (int r = 0; r < weight.size(); ++r)
    if (weight[r] > 0.1) rows += (rows.empty() ? "" : "; ") + model.row_label(r);
  std::ostringstream os;
  os << " (condition estimate " << (s_min > 0 ? format_estimate(s_max / s_min) : "inf")
     << "; involved: " << rows << ")";
  return os.str();
}

// The constraints furthest from being satisfied at q, for messages about failed assembly: the
// largest residual and every row within a factor 10 of it.
std::string largest_residual(const CompiledModel& model, const Eigen::VectorXd& q, double t) {
  ModelEvaluator<double> eval(model);
  Eigen::VectorXd phi(model.nc());
  eval.phi(q.data(), t, phi.data());
  Eigen::Index row = 0;
  const double largest = phi.cwiseAbs().maxCoeff(&row);
  std::string others;
  for (int r = 0; r < phi.size(); ++r)
    if (r != row && std::abs(phi[r]) > 0.1 * largest)
      others += "; " + format_number(phi[r]) + " in " + model.row_label(r);
  return "; largest residual " + format_number(phi[row]) + " in " +
         model.row_label(static_cast<int>(row)) + others;
}

// Rows of Phi_q that depend on earlier rows (file order): adding them does not raise the rank.
std::vector<int> dependent_rows(const Eigen::MatrixXd& scaled, double tol) {
  std::vector<int> dependent;
  Eigen::MatrixXd kept(0, scaled.cols());
  for (int r = 0; r < scaled.rows(); ++r) {
    Eigen::MatrixXd trial(kept.rows() + 1, scaled.cols());
    trial << kept, scaled.row(r);
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(trial.transpose());
    qr.setThreshold(tol);
    if (qr.rank() == trial.rows())
      kept = trial;
    else
      dependent.push_back(r);
  }
  return dependent;
}

}  // namespace

std::string format_number(double value) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", value);
  return buf;
}

void require_driven(const CompiledModel& model) {
  const int nq = model.nq(), nc = model.nc();
  const std::string& file = model.mechanism().source;
  // More equations than coordinates is allowed: run_analysis checks at the assembled position
  // whether they are consistent and redundant (solved by least squares, with a warning) or not.
  if (nc < nq)
    throw InputError(file, "drivers", {},
                     "the mechanism is not kinematically driven: " + std::to_string(nc) +
                         " equations for " + std::to_string(nq) + " coordinates leave " +
                         std::to_string(nq - nc) + " degree(s) of freedom undriven");
}

PointState point_state(const Eigen::Vector3d& q, const Eigen::Vector3d& qd,
                       const Eigen::Vector3d& qdd, const Eigen::Vector2d& s) {
  const double c = std::cos(q[2]), sn = std::sin(q[2]);
  const Eigen::Vector2d as(c * s[0] - sn * s[1], sn * s[0] + c * s[1]);  // A s
  const Eigen::Vector2d bs(-as[1], as[0]);                               // (A s)^perp
  PointState p;
  p.r = q.head<2>() + as;
  p.v = qd.head<2>() + qd[2] * bs;
  p.a = qdd.head<2>() + qdd[2] * bs - qd[2] * qd[2] * as;
  return p;
}

namespace {

// At the assembled configuration: the rank of Phi_q, and the equations that repeat earlier
// ones. Consistent redundancy is solved by least squares with a warning (an error under
// --strict); a rank below nq is left to the solver, which reports it as singular.
void check_redundancy(const CompiledModel& model, const Eigen::VectorXd& q, double t,
                      const AnalysisOptions& options) {
  if (model.nc() <= model.nq()) return;
  const Eigen::MatrixXd scaled = scaled_jacobian(model, jacobian_at(model, q, t));
  const std::vector<int> dependent = dependent_rows(scaled, 1e-9);
  if (dependent.empty()) return;
  std::string names;
  for (int r : dependent) names += (names.empty() ? "" : "; ") + model.row_label(r);
  const int rank = model.nc() - static_cast<int>(dependent.size());
  const std::string what = std::to_string(model.nc()) + " equations for " +
                           std::to_string(model.nq()) + " coordinates, rank " +
                           std::to_string(rank) + " at " + time_text(t) + ": redundant: " + names;
  const std::string& file = model.mechanism().source;
  if (options.strict)
    throw InputError(file, "joints", {},
                     "redundant constraints (" + what + "); --strict rejects them: remove them");
  if (options.warn)
    options.warn(file + ": redundant constraints (" + what +
                 "); solving the consistent system by least squares");
}

// Newton's first steps can move an angle by many turns (a driver at t = 2 pi 1e6 moves its
// crank by 1e6 turns in one step, and the coupler's angle follows by some arbitrary amount).
// Where an angle enters only through sin and cos, whole turns are not seen by Phi: bring each
// such angle back into the turn of its estimate q0, so the first row reads as the file meant.
template <class S>
void keep_turns_of_estimates(S& solver, const CompiledModel& model, Eigen::VectorXd& q, double t) {
  const double two_pi = 2 * std::acos(-1.0);
  const Eigen::VectorXd q0 = model.q0();
  const auto& kinds = model.symbolic().coordinate_kinds;
  for (int k = 0; k < q.size(); ++k) {
    if (kinds[k] != CoordinateKind::kAngle) continue;
    const double turns = std::round((q[k] - q0[k]) / two_pi);
    if (turns == 0) continue;
    Eigen::VectorXd trial = q;
    trial[k] -= turns * two_pi;
    const double wanted = trial[k];
    if (solver.position(trial, t) && std::abs(trial[k] - wanted) < 1e-6) q = trial;
  }
}

std::string singular_diagnosis(const CompiledModel& model, const Solver& solver, const Result&) {
  return singular_rows(model, solver.jacobian());
}

std::string singular_diagnosis(const CompiledModel& model, const LargeSolver& solver,
                               const Result& r) {
  if (model.nq() <= kMaxDiagnosedNq)
    return singular_rows(model, Eigen::MatrixXd(solver.jacobian()));
  return " (condition estimate " + format_estimate(r.condition) + "; " +
         std::to_string(model.nq()) + " coordinates are too many to name the constraints " +
         "involved, at most " + std::to_string(kMaxDiagnosedNq) + ")";
}

// The time loop, on either solver (dense or sparse Phi_q).
template <class S>
void analyze(S& solver, const CompiledModel& model, const TimeGrid& grid,
             const std::function<void(const StateRow&)>& sink, const AnalysisOptions& options) {
  const std::string& file = model.mechanism().source;
  const auto& scales = model.symbolic().coordinate_scales;
  const auto inv_scale = [&](int k) { return 1 / scales[k]; };
  std::vector<int> all_coordinates(model.nq());
  for (int k = 0; k < model.nq(); ++k) all_coordinates[k] = k;
  StateRow row;
  row.q = model.q0();
  row.qd = Eigen::VectorXd::Zero(model.nq());
  row.qdd = Eigen::VectorXd::Zero(model.nq());
  const auto fail = [&](const char* stage, double t, Result r) {
    // Newton that ends near a singular Phi_q (as at a toggle, where it converges only
    // linearly) is reported as singular, as a solved position there is.
    if (r.status == Status::kMaxIterations && r.condition > options.max_condition)
      r.status = Status::kSingular;
    std::string message = file + ": " + stage + " analysis failed at " + time_text(t) + ": " +
                          r.message();
    if (r.status == Status::kMaxIterations || r.status == Status::kInconsistent) {
      if (r.status == Status::kMaxIterations)
        message += " in " + std::to_string(r.iterations) + " iterations (last scaled step " +
                   format_estimate(r.step) + "); the mechanism may not assemble here";
      message += largest_residual(model, row.q, t) + " (condition estimate of Phi_q " +
                 format_estimate(r.condition) + " at the last iterate)";
    }
    if (r.status == Status::kSingular) {
      message += singular_diagnosis(model, solver, r);
      if (std::string(stage) == "position")
        message += "; a toggle or dead-centre position (a driver past what the mechanism can "
                   "reach), or constraints that leave a motion undriven";
    }
    throw AnalysisError(message);
  };
  StateRow previous;
  Eigen::VectorXd qdd_before;  // the acceleration one step before `previous` (the jerk)
  double h_before = 0;
  int previous_sign = 0;
  for (int k = 0; k <= grid.steps; ++k) {
    const double t = grid.at(k);
    if (k > 0) {
      // The runtime's predictor from the last solved state keeps Newton on its branch.
      const double h = t - row.t;
      const TaylorPredictor<double> predict(h, h_before, k > 1);
      for (int c = 0; c < row.q.size(); ++c)
        row.q[c] = predict(row.q[c], row.qd[c], row.qdd[c], k > 1 ? qdd_before[c] : 0.0);
    }
    row.t = t;
    if (auto r = solver.position(row.q, t); !r) {
      // A coarse step can predict a point from which Newton cannot find its way; start once
      // more from the last solution before giving up (the jump check below still applies).
      if (k == 0) fail("position", t, r);
      row.q = previous.q;
      if (auto r2 = solver.position(row.q, t); !r2) fail("position", t, r2);
    }
    if (k == 0) {
      keep_turns_of_estimates(solver, model, row.q, t);
      check_redundancy(model, row.q, t, options);
    }
    if (auto r = solver.velocity(row.q, t, row.qd); !r) {
      fail("velocity", t, r);
    } else if (r.condition > options.max_condition) {
      // Newton converges (slowly) onto a toggle point, where Phi_q is singular only in the
      // limit: velocities there are meaningless, so it counts as singular.
      r.status = Status::kSingular;
      fail("position", t, r);
    }
    if (auto r = solver.acceleration(row.q, row.qd, t, row.qdd); !r) fail("acceleration", t, r);
    if (k > 0 && options.check_jumps) {
      // The runtime's test (kinegen/motion.hpp), the one Solver::step applies.
      const MotionCheck motion = check_motion(
          all_coordinates, t - previous.t, previous.q, previous.qd, previous.qdd, row.q, row.qd,
          row.qdd, inv_scale, options.jump_fraction, std::numeric_limits<double>::epsilon());
      if (motion.jumped())
        throw AnalysisError(
            file + ": position analysis failed at " + time_text(t) +
            ": the solution jumped (scaled change " + format_number(motion.change) + " since " +
            time_text(previous.t) + " disagrees with the velocities by " +
            format_number(motion.miss) +
            "): Newton left the assembly branch it started on, or the step is too coarse to tell; "
            "use smaller steps (--steps)");
      const int sign = solver.jacobian_sign();
      if (previous_sign != 0 && sign != 0 && sign != previous_sign)
        throw AnalysisError(file + ": position analysis failed at " + time_text(t) +
                            ": det(Phi_q) changed sign since " + time_text(previous.t) +
                            ": the solution crossed a singular configuration or jumped to "
                            "another assembly branch; use smaller steps (--steps)");
    }
    previous_sign = solver.jacobian_sign();
    row.points.clear();
    const auto& points = model.mechanism().points;
    for (std::size_t p = 0; p < points.size(); ++p) {
      const int b = 3 * points[p].body;
      row.points.push_back(point_state(row.q.segment<3>(b), row.qd.segment<3>(b),
                                       row.qdd.segment<3>(b), model.point_offsets()[p]));
    }
    sink(row);
    if (k > 0) {
      qdd_before = previous.qdd;
      h_before = t - previous.t;
    }
    previous = row;
  }
}

}  // namespace

void run_analysis(const CompiledModel& model, const TimeGrid& grid,
                  const std::function<void(const StateRow&)>& sink) {
  run_analysis(model, grid, sink, AnalysisOptions{});
}

void run_analysis(const CompiledModel& model, const TimeGrid& grid,
                  const std::function<void(const StateRow&)>& sink,
                  const AnalysisOptions& options) {
  require_driven(model);
  if (model.nq() == model.nc() && model.nq() > options.sparse_above_nq) {
    LargeSolver solver{ProgramSystem(model)};
    analyze(solver, model, grid, sink, options);
  } else {
    Solver solver{ProgramSystem(model)};
    analyze(solver, model, grid, sink, options);
  }
}

std::string csv_header(const Mechanism& m) {
  std::string h = "t";
  for (const auto& b : m.bodies)
    for (const char* c : {"x", "y", "phi", "vx", "vy", "omega", "ax", "ay", "alpha"})
      h += "," + b.name + "." + c;
  for (const auto& p : m.points)
    for (const char* c : {"x", "y", "vx", "vy", "ax", "ay"}) h += "," + p.name + "." + c;
  return h + "\n";
}

std::string csv_row(const StateRow& row) {
  std::string s = format_number(row.t);
  for (int b = 0; b < row.q.size() / 3; ++b) {
    for (int c = 0; c < 3; ++c) s += "," + format_number(row.q[3 * b + c]);
    for (int c = 0; c < 3; ++c) s += "," + format_number(row.qd[3 * b + c]);
    for (int c = 0; c < 3; ++c) s += "," + format_number(row.qdd[3 * b + c]);
  }
  for (const auto& p : row.points)
    for (const Eigen::Vector2d* v : {&p.r, &p.v, &p.a})
      s += "," + format_number((*v)[0]) + "," + format_number((*v)[1]);
  return s + "\n";
}

}  // namespace kinegen::codegen
