#include "kinegen/codegen/analysis.hpp"

#include <kinegen/solver.hpp>

#include <cmath>
#include <cstdio>
#include <sstream>

namespace kinegen::codegen {

namespace {

using Solver = BasicSolver<ProgramSystem>;

std::string time_text(double t) { return "t = " + format_number(t); }

// The constraints behind a singular Phi_q: rows that carry weight in its left null vector.
std::string singular_rows(const CompiledModel& model, const Eigen::MatrixXd& jac) {
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(jac, Eigen::ComputeFullU);
  const Eigen::VectorXd u = svd.matrixU().col(svd.matrixU().cols() - 1);
  const double s_max = svd.singularValues()(0);
  const double s_min = svd.singularValues()(svd.singularValues().size() - 1);
  std::string rows;
  for (int r = 0; r < u.size(); ++r)
    if (std::abs(u[r]) > 0.1) rows += (rows.empty() ? "" : "; ") + model.row_label(r);
  std::ostringstream os;
  os << " (condition estimate " << (s_min > 0 ? format_number(s_max / s_min) : "inf")
     << "; involved: " << rows << ")";
  return os.str();
}

// The constraint furthest from being satisfied at q, for messages about failed assembly.
std::string largest_residual(const CompiledModel& model, const Eigen::VectorXd& q, double t) {
  ModelEvaluator<double> eval(model);
  Eigen::VectorXd phi(model.nc());
  eval.phi(q.data(), t, phi.data());
  Eigen::Index row = 0;
  phi.cwiseAbs().maxCoeff(&row);
  return "; largest residual " + format_number(phi[row]) + " in " +
         model.row_label(static_cast<int>(row));
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
  if (nc < nq)
    throw InputError(file, "drivers", {},
                     "the mechanism is not kinematically driven: " + std::to_string(nc) +
                         " equations for " + std::to_string(nq) + " coordinates leave " +
                         std::to_string(nq - nc) + " degree(s) of freedom undriven");
  if (nc > nq)
    throw InputError(file, "joints", {},
                     std::to_string(nc) + " equations for " + std::to_string(nq) +
                         " coordinates: the constraints are redundant or contradictory; remove "
                         "the extra equations");
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

void run_analysis(const CompiledModel& model, const TimeGrid& grid,
                  const std::function<void(const StateRow&)>& sink) {
  require_driven(model);
  Solver solver{ProgramSystem(model)};
  const std::string& file = model.mechanism().source;
  StateRow row;
  row.q = model.q0();
  row.qd = Eigen::VectorXd::Zero(model.nq());
  row.qdd = Eigen::VectorXd::Zero(model.nq());
  const auto fail = [&](const char* stage, double t, const Result& r) {
    std::string message = file + ": " + stage + " analysis failed at " + time_text(t) + ": " +
                          r.message();
    if (r.status == Status::kMaxIterations)
      message += " in " + std::to_string(r.iterations) + " iterations (last scaled step " +
                 format_number(r.step) + "); the mechanism may not assemble here" +
                 largest_residual(model, row.q, t);
    if (r.status == Status::kSingular) message += singular_rows(model, solver.jacobian());
    throw AnalysisError(message);
  };
  for (int k = 0; k <= grid.steps; ++k) {
    const double t = grid.at(k);
    if (k > 0) {
      // Taylor predictor from the last solved state keeps Newton on its branch.
      const double h = t - row.t;
      row.q += h * row.qd + 0.5 * h * h * row.qdd;
    }
    row.t = t;
    if (auto r = solver.position(row.q, t); !r) fail("position", t, r);
    if (auto r = solver.velocity(row.q, t, row.qd); !r) fail("velocity", t, r);
    if (auto r = solver.acceleration(row.q, row.qd, t, row.qdd); !r) fail("acceleration", t, r);
    row.points.clear();
    const auto& points = model.mechanism().points;
    for (std::size_t p = 0; p < points.size(); ++p) {
      const int b = 3 * points[p].body;
      row.points.push_back(point_state(row.q.segment<3>(b), row.qd.segment<3>(b),
                                       row.qdd.segment<3>(b), model.point_offsets()[p]));
    }
    sink(row);
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
