// SpatialAnalysis (spatial.hpp): the first solve by continuation of the drivers, the branch
// checks and the 3D columns of a spatial file's analysis. The drivers' rows at a chosen value
// and the branch conditions are GiNaC expressions evaluated in double: they run at the first
// solve and once per row, not inside the time loop's Newton iterations.
#include "kinegen/codegen/analysis/spatial.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/constraints/spatial_branch.hpp"

namespace kinegen::codegen {

using GiNaC::ex;

namespace {

// A driver's row with its value as the free variable v (read as t): h(q, v) = 0.
struct ValueRow {
  int row = 0;                               // its row of Phi
  const Constraint* driver;                  // the driver
  ex h;                                      // in q and t (standing for v)
  std::vector<std::pair<int, ex>> gradient;  // dh/dq_k
  ex target;                                 // f(t), in t
  double step = 0.25;                        // the largest change of v per continuation step
};

struct Branch {
  const Constraint* constraint;
  ex value;  // > 0 on the branch
  std::string what;
};

Eigen::Matrix3d tilde(const Eigen::Vector3d& e) {
  Eigen::Matrix3d m;
  m << 0, -e[2], e[1], e[2], 0, -e[0], -e[1], e[0], 0;
  return m;
}

// E(p) = [-e, e~ + e0 I].
Eigen::Matrix<double, 3, 4> e_matrix(const Eigen::Vector4d& p) {
  Eigen::Matrix<double, 3, 4> m;
  m.col(0) = -p.tail<3>();
  m.rightCols<3>() = tilde(p.tail<3>()) + p[0] * Eigen::Matrix3d::Identity();
  return m;
}

// A(p) in the homogeneous form.
Eigen::Matrix3d a_matrix(const Eigen::Vector4d& p) {
  const Eigen::Vector3d e = p.tail<3>();
  return (p[0] * p[0] - e.squaredNorm()) * Eigen::Matrix3d::Identity() + 2 * e * e.transpose() +
         2 * p[0] * tilde(e);
}

}  // namespace

struct SpatialAnalysis::Impl {
  const CompiledModel& model;
  std::vector<ValueRow> drivers;
  std::vector<Branch> branches;
  std::vector<Eigen::Vector3d> points, vectors;

  explicit Impl(const CompiledModel& m) : model(m) {}

  ex params(const ex& e) const {
    return substitute_params(e, model.symbols(), model.symbolic().param_values);
  }
  // e at (q, t). The values enter as the exact binary fractions they are: CLN's double floats
  // trap underflow (a product of tiny Euler parameters), its long floats do not.
  double number(const ex& e, const Eigen::VectorXd& q, double t) const {
    GiNaC::exmap at;
    const SymbolTable& s = model.symbols();
    for (int k = 0; k < s.nq(); ++k) at[s.q(k)] = exact_value(q[k]);
    at[s.t()] = exact_value(t);
    return to_double(e.subs(at));
  }
  static ex exact_value(double v) {
    if (v == 0 || !std::isfinite(v)) return v;
    int e = 0;
    const double m = std::frexp(v, &e);
    return GiNaC::numeric(static_cast<long long>(std::ldexp(m, 53))) *
           GiNaC::pow(GiNaC::numeric(2), e - 53);
  }
};

SpatialAnalysis::SpatialAnalysis(const CompiledModel& model)
    : impl_(std::make_unique<Impl>(model)) {
  const Mechanism& m = model.mechanism();
  const SymbolTable& s = model.symbols();
  const auto& values = model.symbolic().param_values;
  const auto& rows = model.symbolic().rows;
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const Constraint& c = *rows[r].constraint;
    if (!c.is_driver || c.kind->rows == 0) continue;  // expression drivers hold at t
    Constraint by_value = c;
    by_value.value = Expr{"t", c.loc};
    by_value.law = DriverLaw{};
    ValueRow v;
    v.row = static_cast<int>(r);
    v.driver = &c;
    v.h = impl_->params(c.kind->equations(EquationContext(by_value, m, s, values))[0]);
    for (int k = 0; k < s.nq(); ++k)
      if (v.h.has(s.q(k))) v.gradient.emplace_back(k, v.h.diff(s.q(k)));
    v.target = impl_->params(EquationContext(c, m, s, values).value());
    const std::string type = c.type_name();
    if (type != "revolute_angle" && type != "dp1") v.step = 0.1 * model.symbolic().length_scale;
    impl_->drivers.push_back(std::move(v));
  }
  for (const Constraint* c : m.constraints())
    for (auto& [value, what] : branch_conditions(EquationContext(*c, m, s, values)))
      impl_->branches.push_back({c, impl_->params(value), what});
  for (const auto& p : model.symbolic().point_s3)
    impl_->points.emplace_back(to_double(impl_->params(p[0])), to_double(impl_->params(p[1])),
                               to_double(impl_->params(p[2])));
  for (const auto& v : model.symbolic().vectors3)
    impl_->vectors.emplace_back(to_double(impl_->params(v[0])), to_double(impl_->params(v[1])),
                                to_double(impl_->params(v[2])));
}

SpatialAnalysis::~SpatialAnalysis() = default;

void SpatialAnalysis::first_position(Eigen::VectorXd& q, double t) const {
  const Impl& in = *impl_;
  const CompiledModel& model = in.model;
  const int nq = model.nq(), nc = model.nc();
  const auto& scales = model.symbolic().coordinate_scales;
  // Each driver's value at the q0 pose and at t: h(q0, v) = g(q0) - v (or |d|^2 - v^2 for a
  // distance), a revolute_angle's angle0 by its definition.
  std::vector<double> from, to;
  double steps = 1;
  for (const ValueRow& v : in.drivers) {
    double v0 = in.number(v.h, q, 0);
    if (v.driver->kind->squared_distance) v0 = std::sqrt(std::max(v0, 0.0));
    if (std::string(v.driver->type_name()) == "revolute_angle")
      v0 = to_double(in.params(EquationContext(*v.driver, model.mechanism(), model.symbols(),
                                               model.symbolic().param_values)
                                   .scalar("angle0")));
    const double target = in.number(v.target, q, t);
    from.push_back(v0);
    to.push_back(target);
    steps = std::max(steps, std::ceil(std::abs(target - v0) / v.step));
  }
  if (!(steps <= 10000))
    throw AnalysisError(model.mechanism().source + ": position analysis failed at " +
                        format_time(t) +
                        ": the drivers' values at t are not finite or too far "
                        "from the q0 pose");
  ModelEvaluator<double> eval(model);
  Eigen::VectorXd phi(nc);
  Eigen::MatrixXd jac(nc, nq);
  const int n = static_cast<int>(steps);
  for (int i = 1; i <= n; ++i) {
    bool converged = false;
    for (int iteration = 0; iteration < 50 && !converged; ++iteration) {
      eval.phi(q.data(), t, phi.data());
      jac.setZero();
      eval.jacobian(q.data(), t, jac);
      for (std::size_t k = 0; k < in.drivers.size(); ++k) {
        const ValueRow& v = in.drivers[k];
        const double value = from[k] + (to[k] - from[k]) * i / n;
        phi[v.row] = in.number(v.h, q, value);
        jac.row(v.row).setZero();
        for (const auto& [col, d] : v.gradient) jac(v.row, col) = in.number(d, q, value);
      }
      const Eigen::VectorXd dq = jac.completeOrthogonalDecomposition().solve(-phi);
      if (!dq.allFinite()) break;
      q += dq;
      double scaled = 0;
      for (int k = 0; k < nq; ++k) scaled = std::max(scaled, std::abs(dq[k]) / scales[k]);
      converged = scaled < 1e-10;
    }
    if (!converged)
      throw AnalysisError(model.mechanism().source + ": position analysis failed at " +
                          format_time(t) + ": the first solve's continuation from the q0 pose " +
                          "did not converge at step " + std::to_string(i) + " of " +
                          std::to_string(n) +
                          " (check that the bodies' r0 and rot0 are near an assembled pose)");
  }
}

void SpatialAnalysis::check_branches(const Eigen::VectorXd& q, double t) const {
  for (const Branch& b : impl_->branches) {
    const double v = impl_->number(b.value, q, t);
    if (v > 0) continue;
    const Constraint& c = *b.constraint;
    const std::string line = c.loc.line > 0 ? ":" + std::to_string(c.loc.line) : "";
    throw AnalysisError(impl_->model.mechanism().source + line + ": position analysis failed at " +
                        format_time(t) + ": " + c.item + " left its branch (" + b.what + " = " +
                        format_number(v) +
                        ", not > 0): the solve reached the mirrored "
                        "assembly; use smaller steps (--steps) or a q0 pose nearer the motion");
  }
}

std::vector<double> SpatialAnalysis::columns(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                             const Eigen::VectorXd& qdd) const {
  const Mechanism& m = impl_->model.mechanism();
  const int nb = static_cast<int>(m.bodies.size());
  std::vector<double> out;
  std::vector<Eigen::Vector3d> omega(nb), alpha(nb);
  std::vector<Eigen::Matrix3d> rotation(nb);
  const auto put = [&](const Eigen::Vector3d& v) { out.insert(out.end(), v.data(), v.data() + 3); };
  for (int b = 0; b < nb; ++b) {
    const Eigen::Vector4d p = q.segment<4>(7 * b + 3);
    const Eigen::Matrix<double, 3, 4> e = e_matrix(p);
    omega[b] = 2 * e * qd.segment<4>(7 * b + 3);
    alpha[b] = 2 * e * qdd.segment<4>(7 * b + 3);
    rotation[b] = a_matrix(p);
    put(qd.segment<3>(7 * b));
    put(omega[b]);
    put(qdd.segment<3>(7 * b));
    put(alpha[b]);
  }
  // A point (with_origin) or a vector fixed in body b: value, rate, acceleration.
  const auto attached = [&](int b, const Eigen::Vector3d& local, bool with_origin) {
    const Eigen::Vector3d a = rotation[b] * local;
    const Eigen::Vector3d w = omega[b].cross(a);
    const Eigen::Vector3d acc = alpha[b].cross(a) + omega[b].cross(w);
    put(with_origin ? Eigen::Vector3d(q.segment<3>(7 * b) + a) : a);
    put(with_origin ? Eigen::Vector3d(qd.segment<3>(7 * b) + w) : w);
    put(with_origin ? Eigen::Vector3d(qdd.segment<3>(7 * b) + acc) : acc);
  };
  for (std::size_t k = 0; k < m.points.size(); ++k)
    attached(m.points[k].body, impl_->points[k], true);
  for (std::size_t k = 0; k < m.vectors.size(); ++k)
    attached(m.vectors[k].body, impl_->vectors[k], false);
  return out;
}

std::string SpatialAnalysis::csv_row(const StateRow& row, const std::vector<double>& extra) const {
  const int nb = static_cast<int>(impl_->model.mechanism().bodies.size());
  const std::vector<double> rates = columns(row.q, row.qd, row.qdd);
  std::string s = format_number(row.t);
  std::size_t at = 0;
  for (int b = 0; b < nb; ++b) {
    for (int c = 0; c < 7; ++c) s += "," + format_number(row.q[7 * b + c]);
    for (int c = 0; c < 12; ++c) s += "," + format_number(rates[at++]);
  }
  for (; at < rates.size(); ++at) s += "," + format_number(rates[at]);
  for (const auto& o : row.outputs)
    for (double v : o) s += "," + format_number(v);
  for (double v : extra) s += "," + format_number(v);
  // Sensitivities, as sensitivity_columns names them: per parameter the coordinates, the
  // points' and vectors' x, y, z, the outputs.
  for (Eigen::Index k = 0; k < row.dq_dp.cols(); ++k)
    for (const Eigen::MatrixXd* d : {&row.dq_dp, &row.dpoints_dp, &row.doutputs_dp})
      for (Eigen::Index i = 0; i < d->rows(); ++i) s += "," + format_number((*d)(i, k));
  return s + "\n";
}

}  // namespace kinegen::codegen
