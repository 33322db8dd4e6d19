// The minimal-coordinates equations of motion in CLN arithmetic (see
// analysis/reference_dynamics.hpp); the integrator is reference_simulate.cpp.
#include "kinegen/codegen/analysis/reference_dynamics.hpp"

#include <cln/exception.h>

#include <Eigen/Dense>
#include <algorithm>
#include <kinegen/kernels/dynamics.hpp>
#include <kinegen/kernels/newton.hpp>
#include <string>

#include "diagnosis.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/dynamics.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "numeric_lu.hpp"

namespace kinegen::codegen {

using analysis_detail::singular_rows;
using GiNaC::ex;
using GiNaC::numeric;
using Vector = ReferenceDynamics::Vector;

namespace {

constexpr int kMaxIterations = 60;
constexpr const char* kNoSingularPositions =
    "; the reference integrates the minimal coordinates, which cannot pass a singular position";

using Lu = analysis_detail::NumericLu;

numeric dot(const Vector& a, const Vector& b) {
  numeric s = 0;
  for (std::size_t k = 0; k < a.size(); ++k) s = s + a[k] * b[k];
  return s;
}

}  // namespace

struct ReferenceDynamics::Impl {
  Impl(const CompiledModel& model, int digits) : eval(model, digits) {}
  HighPrecisionEvaluator eval;
  // Two tapes, so that each sin and cos of an angle is computed once per position and once
  // per motion: [Phi, the structural non-zeros of Phi_q, g_k(q), dg_k/dq_j (row-major nf x nq),
  // nu] in (q, t), and [gamma, the free rows of gamma at zdd = 0 (-(d/dq (g_k,q qd)) qd), Q^A,
  // Q^nc] in (q, qd, t).
  int position = -1, motion = -1, potential = -1;
  Vector at_position;  // the position tape's last values
  std::vector<int> free_rows;
  std::vector<char> is_free_row;
  bool prescribed = false;  // prescribed drivers do work: their efforts from lambda
  ForceData<numeric> mass;
  std::vector<numeric> inv_scale;
  numeric eps, tolerance, stagnation, quadratic, pivot_ratio;
  Lu lu;
  std::vector<numeric> jac;  // nq x nq row-major at the last solved position
  // Newton's start.
  bool start_moves = false;
  ReferenceMotionState start;
  std::vector<numeric> start_rheonomic;  // qd - B zd: the prescribed drivers' part

  numeric value(const ex& e) const { return eval.to_float(GiNaC::ex_to<numeric>(GiNaC::evalf(e))); }
  // The tapes and the mass data.
  void compile(const CompiledModel& model, const ForceModel& forces, int nf) {
    const SymbolTable& s = model.symbols();
    const SymbolicModel& sym = model.symbolic();
    const int nq = model.nq();
    std::vector<ex> position_outputs = sym.phi, motion_outputs = sym.gamma;
    for (const auto& e : sym.phi_q) position_outputs.push_back(e.value);
    for (const ex& g : sym.free_values) position_outputs.push_back(g);
    for (int k = 0; k < nf; ++k)
      for (int j = 0; j < nq; ++j) position_outputs.push_back(sym.free_values[k].diff(s.q(j)));
    position_outputs.insert(position_outputs.end(), sym.nu.begin(), sym.nu.end());
    for (int k = 0; k < nf; ++k) {
      ex g = 0;
      for (int j = 0; j < nq; ++j) g -= sym.free_rates[k].diff(s.q(j)) * s.qd(j);
      motion_outputs.push_back(g);
    }
    motion_outputs.insert(motion_outputs.end(), forces.applied.begin(), forces.applied.end());
    motion_outputs.insert(motion_outputs.end(), forces.nonconservative.begin(),
                          forces.nonconservative.end());
    position = eval.add_outputs(position_outputs);
    motion = eval.add_outputs(motion_outputs);
    potential = eval.add_outputs({forces.potential});
    const auto values = [&](const std::vector<ex>& v) {
      std::vector<numeric> r;
      for (const ex& e : v) r.push_back(value(e));
      return r;
    };
    mass.mass = values(forces.exact.mass);
    mass.inertia = values(forces.exact.inertia);
    for (const auto& c : forces.exact.com) mass.com.push_back({value(c[0]), value(c[1])});
  }
  // Phi (its free rows g_k(q) - z_k) into f and Phi_q into jac at q, from the position tape.
  void assemble(const CompiledModel& model, const Vector& q, const numeric& t, const Vector& z,
                Vector& f) {
    const auto& sym = model.symbolic();
    const int nq = model.nq(), nc = model.nc(), nf = static_cast<int>(z.size());
    at_position = eval.evaluate(position, q, Vector(nq, numeric(0)), t);
    const Vector& v = at_position;
    f.assign(v.begin(), v.begin() + nc);
    jac.assign(static_cast<std::size_t>(nq) * nq, numeric(0));
    for (std::size_t k = 0; k < sym.phi_q.size(); ++k)
      if (!is_free_row[sym.phi_q[k].row]) jac[sym.phi_q[k].row * nq + sym.phi_q[k].col] = v[nc + k];
    const std::size_t g = nc + sym.phi_q.size();
    for (int k = 0; k < nf; ++k) {
      const int r = free_rows[k];
      f[r] = v[g + k] - z[k];
      for (int j = 0; j < nq; ++j) jac[r * nq + j] = v[g + nf + k * nq + j];
    }
  }
  // Each body's rotated centre of mass A s at q, then M v with _mass_times of
  // kernels/dynamics.hpp.
  Vector ax, ay;
  void set_mass_axes(const Vector& q) {
    const int nb = static_cast<int>(mass.mass.size());
    ax.resize(nb);
    ay.resize(nb);
    for (int b = 0; b < nb; ++b) {
      const numeric c = GiNaC::cos(q[3 * b + 2]), s = GiNaC::sin(q[3 * b + 2]);
      ax[b] = c * mass.com[b][0] - s * mass.com[b][1];
      ay[b] = s * mass.com[b][0] + c * mass.com[b][1];
    }
  }
  Vector mass_times(const Vector& v) const {
    Vector out(v.size());
    kernels::DynamicsKernel::_mass_times(
        static_cast<int>(mass.mass.size()), static_cast<int>(v.size()), mass.mass.data(),
        mass.inertia.data(), ax.data(), ay.data(), v.data(), out.data());
    return out;
  }
};

ReferenceDynamics::ReferenceDynamics(const CompiledModel& model, const ForceModel& forces,
                                     int digits, double t0)
    : model_(model), forces_(forces), nq_(model.nq()) {
  if (digits < kMinReferenceDigits)
    throw UsageError("reference digits must be at least " + std::to_string(kMinReferenceDigits) +
                     ", not " + std::to_string(digits));
  // The free items' checks and the assembled position at t0, in double.
  const ReducedDynamics checked(model, forces, t0);
  const Mechanism& m = model.mechanism();
  const std::vector<int> free = m.free_drivers();
  nf_ = checked.nf();
  const DigitsGuard guard(digits);
  impl_ = std::make_unique<Impl>(model, digits);
  Impl& w = *impl_;
  const SymbolTable& s = model.symbols();
  const SymbolicModel& sym = model.symbolic();
  w.is_free_row.assign(model.nc(), 0);
  const int nj = static_cast<int>(m.joints.size());
  for (int d : free) {
    int row = 0;
    for (int c = 0; c < nj + d; ++c) row += m.constraints()[c]->equation_count();
    w.free_rows.push_back(row);
    w.is_free_row[row] = 1;
  }
  for (const Constraint& c : m.drivers) w.prescribed = w.prescribed || !c.free;
  w.compile(model, forces, nf_);
  const numeric ten = 10;
  w.eps = ten.power(-digits);
  w.tolerance = ten.power(-(digits - 5));
  w.stagnation = ten.power(-(digits / 2));
  w.quadratic = ten.power(-(digits / 3));
  w.pivot_ratio = ten.power(-(digits - 3));
  for (double scale : sym.coordinate_scales)
    w.inv_scale.push_back(w.eval.to_float(numeric(1) / exact_numeric(scale)));
  for (int k = 0; k < nf_; ++k) {
    const std::string type = m.drivers[free[k]].type_name();
    const bool angle = type == "absolute_angle" || type == "relative_angle";
    scales_.push_back(angle ? 1.0 : sym.length_scale);
  }

  // The state at t0: value0 and v0 at D digits (the default value0: the double's, exactly).
  Vector z0(nf_), zd0(nf_);
  for (int k = 0; k < nf_; ++k) {
    const Constraint& c = m.drivers[free[k]];
    const auto exact = [&](const Expr& e, const std::string& what) {
      return w.value(
          substitute_params(s.parse(e, Scope::kGeometry, c.item + what), s, sym.param_values));
    };
    z0[k] = c.free->value0 ? exact(*c.free->value0, " value0")
                           : w.eval.to_float(exact_numeric(checked.initial().z[k]));
    zd0[k] = exact(c.free->v0, " v0");
  }
  w.start.t = to_float(exact_numeric(t0));
  for (int j = 0; j < nq_; ++j)
    w.start.q.push_back(w.eval.to_float(exact_numeric(checked.initial().q[j])));
  w.start_moves = false;
  try {
    evaluate(w.start.t, z0, zd0, initial_);
  } catch (const AnalysisError& e) {
    throw AnalysisError(m.source + ": the reference (" + std::to_string(digits) +
                        " digits) fails at t0 = " + format_time(t0) + ": " + e.what());
  }
  // The same assembly branch as the double simulation.
  for (int j = 0; j < nq_; ++j) {
    const double miss =
        std::abs((initial_.q[j] - exact_numeric(checked.initial().q[j])).to_double()) /
        sym.coordinate_scales[j];
    if (miss > 1e-6)
      throw AnalysisError(m.source + ": the reference assembles at t0 = " + format_time(t0) +
                          " away from the double position (" + s.coord_name(j) + " differs by " +
                          format_estimate(miss) + ")");
  }
}

ReferenceDynamics::~ReferenceDynamics() = default;

int ReferenceDynamics::digits() const { return impl_->eval.digits(); }
numeric ReferenceDynamics::to_float(const numeric& x) const { return impl_->eval.to_float(x); }
HighPrecisionEvaluator& ReferenceDynamics::evaluator() { return impl_->eval; }

void ReferenceDynamics::start_from(const ReferenceMotionState& s) {
  Impl& w = *impl_;
  w.start = s;
  w.start_moves = true;
  w.start_rheonomic = s.qd;
  for (int k = 0; k < nf_; ++k)
    for (int j = 0; j < nq_; ++j)
      w.start_rheonomic[j] = w.start_rheonomic[j] - s.b[k * nq_ + j] * s.zd[k];
}

void ReferenceDynamics::evaluate(const numeric& t, const Vector& z, const Vector& zd,
                                 ReferenceMotionState& out) {
  const DigitsGuard guard(digits());
  if (const std::string table = table_outside(model_.mechanism(), t.to_double()); !table.empty())
    throw AnalysisError("t lies outside " + table);
  out.t = t;
  out.z = z;
  out.zd = zd;
  try {
    solve_position(t, z, out);
    solve_motion(out);
  } catch (const cln::runtime_exception& e) {
    // CLN's own failures (a division by zero, an overflow) are the state's, not the code's.
    throw AnalysisError(std::string("the high-precision arithmetic failed: ") + e.what());
  }
  start_from(out);
}

// Newton for q on the joints', prescribed drivers' and free items' rows, from the start moved
// along B and the drivers' rates; then Phi_q factored at the solution, its conditioning and
// the branch checked.
void ReferenceDynamics::solve_position(const numeric& t, const Vector& z,
                                       ReferenceMotionState& out) {
  using Newton = kernels::NewtonKernel;
  Impl& w = *impl_;
  out.q = w.start.q;
  if (w.start_moves) {
    const numeric dt = t - w.start.t;
    for (int j = 0; j < nq_; ++j) {
      numeric v = out.q[j] + dt * w.start_rheonomic[j];
      for (int k = 0; k < nf_; ++k) v = v + w.start.b[k * nq_ + j] * (z[k] - w.start.z[k]);
      out.q[j] = v;
    }
  }
  const Vector predicted = out.q;
  Vector f;
  numeric last_step = 0;
  bool converged = false;
  for (int it = 0; it < kMaxIterations && !converged; ++it) {
    w.assemble(model_, out.q, t, z, f);
    if (!w.lu.factor(w.jac, nq_, w.pivot_ratio))
      throw AnalysisError("position solve failed: the constraint Jacobian Phi_q is singular");
    const Vector dq = w.lu.solve(f);
    numeric size = 0;
    bool small = true;
    for (int j = 0; j < nq_; ++j) {
      out.q[j] = out.q[j] - dq[j];
      const numeric d = GiNaC::abs(dq[j] * w.inv_scale[j]);
      size = std::max(size, d);
      small = small &&
              Newton::_step_converged(d, GiNaC::abs(out.q[j] * w.inv_scale[j]), w.tolerance, w.eps);
    }
    // In the quadratic phase (a step below 10^-(D/3) and shrinking), the error after this
    // step is about size^3 / last_step^2: below 10^-D, one more iteration would not move q.
    const bool quadratic = size < w.quadratic && size < last_step &&
                           size * size * size <= w.eps * last_step * last_step;
    converged = small || quadratic || Newton::_stalled(size, last_step, w.stagnation);
    last_step = size;
  }
  if (!converged)
    throw AnalysisError("position solve failed: Newton did not converge in " +
                        std::to_string(kMaxIterations) + " iterations");
  w.assemble(model_, out.q, t, z, f);
  check_position(out.q, predicted, f);
}

// The residual recheck (rows scaled by their largest |entry| times the column's scale), then
// Phi_q factored at the solution (which the velocity, the acceleration and B share), its
// conditioning and the branch.
void ReferenceDynamics::check_position(const Vector& q, const Vector& predicted, const Vector& f) {
  Impl& w = *impl_;
  numeric residual = 0;
  for (int r = 0; r < nq_; ++r) {
    numeric size = 0;
    for (int j = 0; j < nq_; ++j)
      size = std::max(size, GiNaC::abs(w.jac[r * nq_ + j]) / w.inv_scale[j]);
    residual = std::max(residual, GiNaC::abs(f[r]) / (size.is_zero() ? numeric(1) : size));
  }
  if (residual > w.stagnation)
    throw AnalysisError("position solve failed: the residual " +
                        format_estimate(residual.to_double()) + " is not below 1e-" +
                        std::to_string(digits() / 2));
  Eigen::MatrixXd jd(nq_, nq_);
  for (int r = 0; r < nq_; ++r)
    for (int j = 0; j < nq_; ++j) jd(r, j) = w.jac[r * nq_ + j].to_double();
  const double rcond = Eigen::PartialPivLU<Eigen::MatrixXd>(scaled_jacobian(model_, jd)).rcond();
  if (!w.lu.factor(w.jac, nq_, w.pivot_ratio) || !(rcond * kSingularCondition > 1))
    throw AnalysisError(
        "the mechanism reached a singular position, where q is not a function of the free "
        "coordinates" +
        singular_rows(model_, jd) + kNoSingularPositions);
  if (!w.start_moves) return;
  numeric change = 0, miss = 0;
  for (int j = 0; j < nq_; ++j) {
    change = std::max(change, GiNaC::abs((predicted[j] - w.start.q[j]) * w.inv_scale[j]));
    miss = std::max(miss, GiNaC::abs((q[j] - predicted[j]) * w.inv_scale[j]));
  }
  if (miss > numeric(kBranchJumpFraction) * change + w.stagnation)
    throw AnalysisError("the position left its assembly branch (it misses the prediction by " +
                        format_estimate(miss.to_double()) + ", the predicted change being " +
                        format_estimate(change.to_double()) + ")" + singular_rows(model_, jd) +
                        kNoSingularPositions);
}

// qd, c and B from the factored Phi_q; the reduced accelerations; the power.
void ReferenceDynamics::solve_motion(ReferenceMotionState& out) {
  Impl& w = *impl_;
  const numeric& t = out.t;
  const int nb = static_cast<int>(model_.mechanism().bodies.size());
  const int nc = model_.nc();
  // nu at the solved position: the position tape's last values (the residual recheck's).
  const Vector prescribed_nu(w.at_position.end() - nc, w.at_position.end());
  Vector nu = prescribed_nu;
  for (int k = 0; k < nf_; ++k) nu[w.free_rows[k]] = out.zd[k];
  out.qd = w.lu.solve(nu);
  const Vector v = w.eval.evaluate(w.motion, out.q, out.qd, t);
  Vector gamma(v.begin(), v.begin() + nc);
  for (int k = 0; k < nf_; ++k) gamma[w.free_rows[k]] = v[nc + k];
  const Vector applied(v.begin() + nc + nf_, v.begin() + nc + nf_ + nq_);
  const Vector nonconservative(v.begin() + nc + nf_ + nq_, v.end());
  const Vector c = w.lu.solve(gamma);
  w.set_mass_axes(out.q);
  out.b.assign(static_cast<std::size_t>(nq_) * nf_, numeric(0));
  std::vector<Vector> columns(nf_), mass_columns(nf_);
  for (int k = 0; k < nf_; ++k) {
    Vector e(nq_, numeric(0));
    e[w.free_rows[k]] = 1;
    columns[k] = w.lu.solve(e);
    std::copy(columns[k].begin(), columns[k].end(), out.b.begin() + k * nq_);
    mass_columns[k] = w.mass_times(columns[k]);
  }
  // g = Q^A + the inertia forces at qdd = c; M_z zdd = B^T g.
  Vector g = applied;
  add_inertia_forces(w.mass, nb, out.q.data(), out.qd.data(), c.data(), g.data());
  std::vector<numeric> reduced(static_cast<std::size_t>(nf_) * nf_);
  Vector rhs(nf_);
  for (int i = 0; i < nf_; ++i) {
    rhs[i] = dot(columns[i], g);
    for (int j = 0; j < nf_; ++j) reduced[i * nf_ + j] = dot(columns[i], mass_columns[j]);
  }
  Lu reduced_lu;
  if (!reduced_lu.factor(reduced, nf_, w.pivot_ratio))
    throw AnalysisError("the reduced mass B^T M B is singular: a free coordinate moves no mass");
  out.zdd = reduced_lu.solve(rhs);
  out.qdd = c;
  for (int k = 0; k < nf_; ++k)
    for (int j = 0; j < nq_; ++j) out.qdd[j] = out.qdd[j] + columns[k][j] * out.zdd[k];
  // The power: qd . Q^nc, and the prescribed drivers' -lambda_r nu_r, with
  // Phi_q^T lambda = Q^A + the inertia forces of the motion.
  out.power = dot(out.qd, nonconservative);
  if (w.prescribed) {
    Vector total = applied;
    add_inertia_forces(w.mass, nb, out.q.data(), out.qd.data(), out.qdd.data(), total.data());
    const Vector lambda = w.lu.solve_transposed(total);
    for (int r = 0; r < model_.nc(); ++r)
      if (!w.is_free_row[r]) out.power = out.power - lambda[r] * prescribed_nu[r];
  }
}

std::array<numeric, 2> ReferenceDynamics::energy(const ReferenceMotionState& s) {
  Impl& w = *impl_;
  const DigitsGuard guard(digits());
  w.set_mass_axes(s.q);
  const numeric kinetic = dot(s.qd, w.mass_times(s.qd)) / 2;
  const numeric potential = w.eval.evaluate(w.potential, s.q, s.qd, s.t)[0];
  return {kinetic, potential};
}

// run_reference_simulation's double rows, and the checks before a run (reference_simulate.cpp
// integrates).

SimulatedRow to_simulated_row(const ReferenceSimulatedRow& r) {
  SimulatedRow s;
  s.state = to_state_row(r.row);
  const auto vec = [](const std::vector<numeric>& v) {
    Eigen::VectorXd d(v.size());
    for (std::size_t k = 0; k < v.size(); ++k) d[k] = v[k].to_double();
    return d;
  };
  s.z = vec(r.z);
  s.zd = vec(r.zd);
  s.zdd = vec(r.zdd);
  for (const numeric& f : r.forces) s.state.forces.push_back(f.to_double());
  s.kinetic = r.kinetic.to_double();
  s.potential = r.potential.to_double();
  s.work = r.work.to_double();
  s.balance = r.balance.to_double();
  return s;
}

void check_reference_digits(int digits) {
  if (digits < kMinSimulateReferenceDigits || digits > kMaxSimulateReferenceDigits)
    throw UsageError("--reference must be between " + std::to_string(kMinSimulateReferenceDigits) +
                     " and " + std::to_string(kMaxSimulateReferenceDigits) + " digits, not " +
                     std::to_string(digits));
}

void check_reference_stop_when(const CompiledModel& model) {
  const Mechanism& m = model.mechanism();
  if (!m.stop_when || model.symbolic().stop_force_columns.empty()) return;
  throw InputError(m.source, "stop_when", m.stop_when->loc,
                   "'" + m.stop_when->text +
                       "' reads force columns, whose rate --reference does not have: it could "
                       "not bound its steps by it and might step over the first crossing; run "
                       "without --reference, or write stop_when without force columns");
}

namespace {

// "" when every value of the row is finite, else which one is not (the outputs' accelerations
// apart: an output that reads velocities has none, nan by the format).
std::string finite_row(const SimulatedRow& r) {
  const auto all = [](const Eigen::VectorXd& v) { return v.allFinite(); };
  if (!all(r.state.q) || !all(r.state.qd) || !all(r.state.qdd)) return "a coordinate";
  if (!all(r.z) || !all(r.zd) || !all(r.zdd)) return "a free coordinate";
  for (const auto& p : r.state.points)
    if (!p.r.allFinite() || !p.v.allFinite() || !p.a.allFinite()) return "a point";
  for (const auto& o : r.state.outputs)
    if (!std::isfinite(o[0]) || !std::isfinite(o[1])) return "an output";
  for (double f : r.state.forces)
    if (!std::isfinite(f)) return "a force column";
  for (double e : {r.kinetic, r.potential, r.work, r.balance})
    if (!std::isfinite(e)) return "an energy column";
  return "";
}

}  // namespace

ReferenceSimulationStats run_reference_simulation(
    const CompiledModel& model, const ForceModel& forces, const TimeGrid& grid, int digits,
    const std::function<void(const SimulatedRow&)>& sink, const SimulateOptions& options) {
  return run_reference_simulation_exact(
      model, forces, grid, digits,
      [&](const ReferenceSimulatedRow& row) {
        const SimulatedRow r = to_simulated_row(row);
        // Exact values beyond double's range (a table of 1e308) would round to inf: the run
        // ends before such a row (docs/format.md, Simulation: a row is never non-finite).
        std::string what = finite_row(r);
        if (!what.empty())
          throw AnalysisError(model.mechanism().source + ": reference simulation: at " +
                              format_time(r.state.t) + " " + what +
                              " is beyond double's range; the rows before are kept");
        sink(r);
      },
      options);
}

}  // namespace kinegen::codegen
