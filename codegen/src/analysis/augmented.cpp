// The augmented Lagrangian method for singular positions (see analysis/augmented.hpp): Bayo,
// Garcia de Jalon and Serna's index-1 formulation (CMAME 71, 1988) with Bayo and Ledesma's
// mass-orthogonal projections (Nonlinear Dynamics 9, 1996), as a MotionFormulation for CVODE.
#include "kinegen/codegen/analysis/augmented.hpp"

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <kinegen/kernels/dynamics.hpp>
#include <limits>

#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "diagnosis.hpp"
#include "kinegen/codegen/model/table.hpp"

namespace kinegen::codegen {

namespace {

using K = kernels::DynamicsKernel;
using Vec = Eigen::VectorXd;

// Up to this many coordinates M + alpha Phi_q^T Phi_q is factored dense, beyond as sparse.
constexpr int kDenseLimit = 48;
// The lambda* iteration ends where qdd (or a projection's correction) changes by less than
// this, relative to its size: far below any --rtol, so that the evaluations' dependence on
// the iteration count is no noise the integrator sees.
constexpr double kIterationTolerance = 1e-13;
// Newton steps of the position projection (2 suffice off singular positions).
constexpr int kPositionIterations = 8;

// The rows of Phi_q that are constraints here (joints and prescribed drivers), compressed by
// row: entry e of row i is at column col[e], value[e], taken from the phi_q program's
// output source[e].
struct ConstraintRows {
  std::vector<int> rows;  // rows of Phi kept, m
  std::vector<int> start, col, source;
  std::vector<double> value;

  int m() const { return static_cast<int>(rows.size()); }
  void gather(const std::vector<double>& jac_values) {
    for (std::size_t e = 0; e < col.size(); ++e) value[e] = jac_values[source[e]];
  }
  void times(const Vec& x, Vec& out) const {  // out = J x
    out.setZero(m());
    for (int i = 0; i < m(); ++i)
      for (int e = start[i]; e < start[i + 1]; ++e) out[i] += value[e] * x[col[e]];
  }
  void add_transpose_times(const Vec& w, Vec& out) const {  // out += J^T w
    for (int i = 0; i < m(); ++i)
      for (int e = start[i]; e < start[i + 1]; ++e) out[col[e]] += value[e] * w[i];
  }
};

// M + J^T diag(alpha) J, factored: dense Cholesky up to kDenseLimit coordinates, beyond the
// sparse LDL^T, whose pattern is analysed once (the structural non-zeros never change).
class AugmentedMatrix {
 public:
  AugmentedMatrix(int nq, const ConstraintRows& j) : nq_(nq), j_(j), dense_(nq <= kDenseLimit) {}

  // blocks: M's 3 x 3 block per body (row-major); massless coordinates after them. false:
  // not positive definite.
  bool factor(const std::vector<std::array<double, 9>>& blocks, const Vec& alpha) {
    const int nb = static_cast<int>(blocks.size());
    if (dense_) {
      a_.setZero(nq_, nq_);
      for (int b = 0; b < nb; ++b)
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) a_(3 * b + r, 3 * b + c) = blocks[b][3 * r + c];
      for (int i = 0; i < j_.m(); ++i)
        for (int e = j_.start[i]; e < j_.start[i + 1]; ++e)
          for (int f = j_.start[i]; f < j_.start[i + 1]; ++f)
            a_(j_.col[e], j_.col[f]) += alpha[i] * j_.value[e] * j_.value[f];
      llt_.compute(a_);
      return llt_.info() == Eigen::Success;
    }
    triplets_.clear();
    for (int b = 0; b < nb; ++b)
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c <= r; ++c)
          triplets_.emplace_back(3 * b + r, 3 * b + c, blocks[b][3 * r + c]);
    for (int k = 3 * nb; k < nq_; ++k) triplets_.emplace_back(k, k, 0.0);
    for (int i = 0; i < j_.m(); ++i)
      for (int e = j_.start[i]; e < j_.start[i + 1]; ++e)
        for (int f = j_.start[i]; f < j_.start[i + 1]; ++f)
          if (j_.col[f] <= j_.col[e])
            triplets_.emplace_back(j_.col[e], j_.col[f], alpha[i] * j_.value[e] * j_.value[f]);
    s_.resize(nq_, nq_);
    s_.setFromTriplets(triplets_.begin(), triplets_.end());
    if (!analyzed_) ldlt_.analyzePattern(s_);
    analyzed_ = true;
    ldlt_.factorize(s_);
    return ldlt_.info() == Eigen::Success && ldlt_.vectorD().minCoeff() > 0;
  }
  void solve(Vec& x) const { x = dense_ ? Vec(llt_.solve(x)) : Vec(ldlt_.solve(x)); }

 private:
  int nq_;
  const ConstraintRows& j_;
  bool dense_;
  Eigen::MatrixXd a_;
  Eigen::LLT<Eigen::MatrixXd> llt_;
  std::vector<Eigen::Triplet<double>> triplets_;
  Eigen::SparseMatrix<double> s_;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> ldlt_;
  bool analyzed_ = false;
};

class AugmentedLagrangian : public MotionFormulation {
 public:
  AugmentedLagrangian(const CompiledModel& model, const ForceModel& forces, double t0,
                      const AugmentedSettings& settings);

  int size() const override { return 2 * nq_; }
  Eigen::VectorXd initial() const override { return y0_; }
  Eigen::VectorXd scales() const override {
    Vec s(2 * nq_);
    s << scale_, scale_;
    return s;
  }
  bool rhs(double t, const double* y, double* ydot) override;
  const MotionState& state() const override { return state_; }
  Energy energy() override;
  double activity(const Energy& e) override;
  MotionFailure failure() const override { return failure_; }
  const std::string& reason() const override { return reason_; }
  bool has_projection() const override { return true; }
  bool project(double t, const double* y, double* correction) override;
  bool project_error(double t, double* error) override;
  std::string diagnose(double t, const double* y) override {
    std::string rows;
    if (nq_ <= analysis_detail::kMaxDiagnosedNq)
      rows = analysis_detail::singular_rows(
          model_, analysis_detail::jacobian_at(model_, Vec::Map(y, nq_), t));
    return "the augmented method could not pass this position: its error test failed "
           "repeatedly with Phi_q there" +
           (rows.empty() ? std::string(" not examined (more than ") +
                               std::to_string(analysis_detail::kMaxDiagnosedNq) + " coordinates)"
                         : rows) +
           "; near a singular position the projections' rounding can exceed the absolute "
           "tolerance: try a looser --atol (such as 1e-13) or --rtol";
  }

 private:
  bool fail(MotionFailure f, std::string reason) {
    failure_ = f;
    reason_ = std::move(reason);
    return false;
  }
  bool check_input(double t, const double* y);
  void mass_at(const Vec& q);
  void mass_times(const Vec& v, Vec& out) const {
    out.resize(nq_);
    K::_mass_times(nb_, nq_, mass_m_.data(), mass_j_.data(), mass_ax_.data(), mass_ay_.data(),
                   v.data(), out.data());
  }
  bool jacobian_at(const Vec& q, double t);
  bool accelerations(MotionState& s, Vec& lambda);
  bool factor();
  void choose_constants(const MotionState& s0, const AugmentedSettings& settings);
  int solve_constrained(const Vec& f, const Vec& h, double floor, Vec& x, Vec& lambda);
  void free_coordinates(MotionState& s);

  const CompiledModel& model_;
  const ForceModel& forces_;
  int nq_ = 0, nb_ = 0, nf_ = 0;
  ModelEvaluator<double> eval_;
  std::shared_ptr<const ForcePrograms> programs_;  // the compile stage's
  ProgramEvaluator<double> applied_, nonconservative_, potential_;
  ProgramEvaluator<double> free_value_, free_rate_, free_gradient_, free_a0_;
  ConstraintRows j_;
  AugmentedMatrix a_;
  Vec alpha_, row_scale_, scale_, y0_;
  Vec lambda_start_;  // the last step's multipliers, the next evaluations' start
  double xi_ = 1, omega_ = 10, tau_ = 1;
  int max_iterations_ = 100;
  // Work space.
  std::vector<double> jac_values_, all_rows_, all_nu_, all_gamma_;
  std::vector<std::array<double, 9>> blocks_;
  Vec mass_m_, mass_j_, mass_ax_, mass_ay_, phi_, nu_, lambda_;
  double constraint_power_ = 0;  // -lambda^T nu at state_
  MotionState state_;
  MotionFailure failure_ = MotionFailure::kNone;
  std::string reason_;
};

AugmentedLagrangian::AugmentedLagrangian(const CompiledModel& model, const ForceModel& forces,
                                         double t0, const AugmentedSettings& settings)
    : model_(model),
      forces_(forces),
      nq_(model.nq()),
      nb_(static_cast<int>(model.mechanism().bodies.size())),
      nf_(model.mechanism().num_free()),
      eval_(model),
      programs_(model.force_programs(forces)),
      applied_(programs_->applied),
      nonconservative_(programs_->nonconservative),
      potential_(programs_->potential),
      free_value_(model.free_programs().values),
      free_rate_(model.free_programs().rates),
      free_gradient_(model.free_programs().gradient),
      free_a0_(model.free_programs().a0),
      a_(model.nq(), j_),
      scale_(Vec::Map(model.symbolic().coordinate_scales.data(), model.nq())) {
  // The start and the free items' checks at t0: the minimal method's (InputError on bad input).
  const MotionState s0 = ReducedDynamics(model, forces, t0).initial();
  // The constraints: every row of Phi but the free items'.
  const Mechanism& m = model.mechanism();
  std::vector<int> row_index(model.nc(), 0);
  const int nj = static_cast<int>(m.joints.size());
  for (int d : m.free_drivers())
    for (int r = forces.row_begin[nj + d]; r < forces.row_begin[nj + d + 1]; ++r) row_index[r] = -1;
  for (int r = 0; r < model.nc(); ++r)
    if (row_index[r] == 0) {
      row_index[r] = j_.m();
      j_.rows.push_back(r);
    }
  const auto& p = model.programs();
  j_.start.assign(j_.m() + 1, 0);
  for (std::size_t e = 0; e < p.jac_rows.size(); ++e)
    if (row_index[p.jac_rows[e]] >= 0) ++j_.start[row_index[p.jac_rows[e]] + 1];
  for (int i = 0; i < j_.m(); ++i) j_.start[i + 1] += j_.start[i];
  j_.col.resize(j_.start.back());
  j_.source.resize(j_.start.back());
  j_.value.resize(j_.start.back());
  std::vector<int> fill(j_.start.begin(), j_.start.end() - 1);
  for (std::size_t e = 0; e < p.jac_rows.size(); ++e) {
    const int i = row_index[p.jac_rows[e]];
    if (i < 0) continue;
    j_.col[fill[i]] = p.jac_cols[e];
    j_.source[fill[i]++] = static_cast<int>(e);
  }
  jac_values_.resize(p.jac_rows.size());
  all_rows_.resize(model.nc());
  all_nu_.resize(model.nc());
  all_gamma_.resize(model.nc());
  choose_constants(s0, settings);
  y0_.resize(2 * nq_);
  y0_ << s0.q, s0.qd;
  state_ = s0;
  // The multipliers at t0, from lambda = 0 (a regular position: a few iterations), start the
  // first step's evaluations.
  Vec ydot(2 * nq_);
  if (rhs(t0, y0_.data(), ydot.data())) lambda_start_ = lambda_;
}

// alpha, omega and xi (augmented.hpp, AugmentedSettings), from M and Phi_q at t0.
void AugmentedLagrangian::choose_constants(const MotionState& s0,
                                           const AugmentedSettings& settings) {
  const auto& kinds = model_.symbolic().coordinate_kinds;
  mass_at(s0.q);
  jacobian_at(s0.q, s0.t);
  Vec diagonal = Vec::Zero(nq_);
  for (int b = 0; b < nb_; ++b)
    for (int r = 0; r < 3; ++r) diagonal[3 * b + r] = blocks_[b][4 * r];
  // A massless coordinate weighs as the heaviest of its kind, for the scale only.
  Vec weight = diagonal;
  for (int k = 0; k < nq_; ++k) {
    if (weight[k] > 0) continue;
    double heaviest = 0;
    for (int c = 0; c < nq_; ++c)
      if (kinds[c] == kinds[k]) heaviest = std::max(heaviest, diagonal[c]);
    weight[k] = heaviest > 0 ? heaviest : std::max(diagonal.maxCoeff(), 1.0);
  }
  alpha_.resize(j_.m());
  row_scale_.resize(j_.m());
  for (int i = 0; i < j_.m(); ++i) {
    double w = 0, largest = 0;
    for (int e = j_.start[i]; e < j_.start[i + 1]; ++e) {
      w = std::max(w, j_.value[e] * j_.value[e] / weight[j_.col[e]]);
      largest = std::max(largest, std::abs(j_.value[e]) * scale_[j_.col[e]]);
    }
    alpha_[i] = settings.penalty / (w > 0 ? w : 1 / weight.maxCoeff());
    row_scale_[i] = largest > 0 ? largest : 1;
  }
  double rate = 0;
  for (int k = 0; k < nq_; ++k) {
    rate = std::max(rate, std::sqrt(std::abs(s0.qdd[k]) / scale_[k]));
    rate = std::max(rate, std::abs(s0.qd[k]) / scale_[k]);
  }
  tau_ = rate > 0 && std::isfinite(rate) ? 1 / rate : 1.0;
  omega_ = settings.omega > 0 ? settings.omega : std::acos(-1.0) / tau_;
  xi_ = settings.xi;
  max_iterations_ = std::max(settings.max_iterations, 1);
}

// Each body's mass data at q: for the kernel's M v and as M's 3 x 3 blocks.
void AugmentedLagrangian::mass_at(const Vec& q) {
  const ForceData<double>& d = forces_.numbers;
  mass_m_.resize(nb_);
  mass_j_.resize(nb_);
  mass_ax_.resize(nb_);
  mass_ay_.resize(nb_);
  blocks_.resize(nb_);
  for (int b = 0; b < nb_; ++b) {
    const double c = std::cos(q[3 * b + 2]), s = std::sin(q[3 * b + 2]);
    const double ax = c * d.com[b][0] - s * d.com[b][1], ay = s * d.com[b][0] + c * d.com[b][1];
    const double m = d.mass[b];
    mass_m_[b] = m;
    mass_j_[b] = d.inertia[b];
    mass_ax_[b] = ax;
    mass_ay_[b] = ay;
    // The block _mass_times multiplies by: the centre of mass at A s from the frame's origin.
    blocks_[b] = {
        m, 0, -m * ay, 0, m, m * ax, -m * ay, m * ax, d.inertia[b] + m * (ax * ax + ay * ay)};
  }
}

// Phi, Phi_q, nu of the constraint rows at (q, t); false when a value is not finite.
bool AugmentedLagrangian::jacobian_at(const Vec& q, double t) {
  eval_.phi_q_values(q.data(), t, jac_values_.data());
  eval_.phi(q.data(), t, all_rows_.data());
  eval_.nu(q.data(), t, all_nu_.data());
  j_.gather(jac_values_);
  phi_.resize(j_.m());
  nu_.resize(j_.m());
  for (int i = 0; i < j_.m(); ++i) {
    phi_[i] = all_rows_[j_.rows[i]];
    nu_[i] = all_nu_[j_.rows[i]];
  }
  return phi_.allFinite() && nu_.allFinite() &&
         std::all_of(j_.value.begin(), j_.value.end(), [](double v) { return std::isfinite(v); });
}

bool AugmentedLagrangian::factor() {
  if (a_.factor(blocks_, alpha_)) return true;
  return fail(MotionFailure::kPosition,
              "M + alpha Phi_q^T Phi_q is not positive definite: a coordinate that no joint or "
              "driver holds moves no mass");
}

// x with M x + J^T lambda = f and J x = h (the minimum of 1/2 x^T M x - f^T x on J x = h), by
// the augmented Lagrangian iteration lambda_{i+1} = lambda_i + alpha (J x_i - h) on the
// factored M + J^T alpha J, in residual form: each step solves for the change of x from the
// residual of the unpenalized equations, so that the penalty's conditioning costs no
// accuracy. lambda: the start on entry (the literature's: the last step's multipliers), the
// multipliers on return (which carry the penalty's rounding, alpha times that of J x - h; x
// does not). Ends where x changes by less than kIterationTolerance times max(|x|, floor)
// (coordinate-scaled). Where Phi_q has lost rank the iteration converges slowly in the directions
// that became free, whose constraint residual J x - h vanishes with the rank, and stops after
// max_iterations_. Returns the iterations.
int AugmentedLagrangian::solve_constrained(const Vec& f, const Vec& h, double floor, Vec& x,
                                           Vec& lambda) {
  const int m = j_.m();
  Vec c(m), r(nq_), mx(nq_), w(m);
  if (lambda.size() != m) lambda.setZero(m);
  x = f;
  j_.add_transpose_times(alpha_.cwiseProduct(h) - lambda, x);
  a_.solve(x);
  int it = 1;
  for (; it <= max_iterations_; ++it) {
    j_.times(x, c);
    c -= h;
    lambda += alpha_.cwiseProduct(c);
    mass_times(x, mx);
    r = f - mx;
    w = -(lambda + alpha_.cwiseProduct(c));
    j_.add_transpose_times(w, r);
    a_.solve(r);
    x += r;
    const double change = r.cwiseQuotient(scale_).cwiseAbs().maxCoeff();
    const double size =
        kIterationTolerance * std::max(x.cwiseQuotient(scale_).cwiseAbs().maxCoeff(), floor);
    if (!(change > size)) break;
  }
  j_.times(x, c);
  lambda += alpha_.cwiseProduct(c - h);
  return it;
}

bool AugmentedLagrangian::check_input(double t, const double* y) {
  failure_ = MotionFailure::kNone;
  reason_.clear();
  if (const std::string table = table_outside(model_.mechanism(), t); !table.empty())
    return fail(MotionFailure::kOutsideTable, "t lies outside " + table);
  for (int k = 0; k < 2 * nq_; ++k)
    if (!std::isfinite(y[k])) return fail(MotionFailure::kNonFinite, "the state is not finite");
  return true;
}

bool AugmentedLagrangian::rhs(double t, const double* y, double* ydot) {
  if (!check_input(t, y)) return false;
  MotionState& s = state_;
  s.t = t;
  s.q = Vec::Map(y, nq_);
  s.qd = Vec::Map(y + nq_, nq_);
  if (!jacobian_at(s.q, t))
    return fail(MotionFailure::kNonFinite, "a constraint or its Jacobian is not finite");
  mass_at(s.q);
  if (!factor() || !accelerations(s, lambda_)) return false;
  free_coordinates(s);
  for (int k = 0; k < nq_; ++k) {
    ydot[k] = s.qd[k];
    ydot[nq_ + k] = s.qdd[k];
  }
  return true;
}

// qdd and the multipliers at s.t, s.q, s.qd, with Phi_q and M + alpha Phi_q^T Phi_q there
// evaluated and factored, from the last step's multipliers.
bool AugmentedLagrangian::accelerations(MotionState& s, Vec& lambda) {
  eval_.gamma(s.q.data(), s.qd.data(), s.t, all_gamma_.data());
  // Q = Q^A + the quadratic velocity forces (the inertia forces at qdd = 0).
  Vec q_total(nq_), zero = Vec::Zero(nq_);
  applied_.run(s.q.data(), s.qd.data(), s.t, model_.params().data(), q_total.data());
  add_inertia_forces(forces_.numbers, nb_, s.q.data(), s.qd.data(), zero.data(), q_total.data());
  // The stabilized constraint accelerations: Phi_ddot + 2 xi omega Phi_dot + omega^2 Phi = 0,
  // Phi_ddot = Phi_q qdd - gamma, Phi_dot = Phi_q qd - nu.
  Vec velocity_error(j_.m()), h(j_.m());
  j_.times(s.qd, velocity_error);
  velocity_error -= nu_;
  for (int i = 0; i < j_.m(); ++i)
    h[i] =
        all_gamma_[j_.rows[i]] - 2 * xi_ * omega_ * velocity_error[i] - omega_ * omega_ * phi_[i];
  if (!q_total.allFinite() || !h.allFinite())
    return fail(MotionFailure::kNonFinite,
                "a non-finite value in the generalized forces or gamma (a load, a table or the "
                "state)");
  lambda = lambda_start_;
  solve_constrained(q_total, h, 1 / (tau_ * tau_), s.qdd, lambda);
  // The constraints' power -lambda^T nu (the prescribed drivers'; the joints' nu is 0), as
  // -(J^T lambda)^T qd + lambda^T (J qd - nu) with J^T lambda = Q - M qdd: lambda itself
  // carries the penalty's rounding (alpha times that of J qd - h), J^T lambda does not, and
  // the second term is as small as the velocity constraints' residual.
  Vec constraint_force(nq_);
  mass_times(s.qdd, constraint_force);
  constraint_force = q_total - constraint_force;
  constraint_power_ = -constraint_force.dot(s.qd) + lambda.dot(velocity_error);
  if (!s.qdd.allFinite())
    return fail(MotionFailure::kNonFinite, "the accelerations are not finite");
  return true;
}

// The free items' z, zd, zdd read off q, qd, qdd.
void AugmentedLagrangian::free_coordinates(MotionState& s) {
  const double* params = model_.params().data();
  s.z.resize(nf_);
  s.zd.resize(nf_);
  s.zdd.resize(nf_);
  free_value_.run(s.q.data(), nullptr, s.t, params, s.z.data());
  free_rate_.run(s.q.data(), s.qd.data(), s.t, params, s.zd.data());
  free_a0_.run(s.q.data(), s.qd.data(), s.t, params, s.zdd.data());
  std::vector<double> gradient(static_cast<std::size_t>(nf_) * nq_);
  free_gradient_.run(s.q.data(), nullptr, s.t, params, gradient.data());
  for (int k = 0; k < nf_; ++k)
    for (int c = 0; c < nq_; ++c) s.zdd[k] += gradient[k * nq_ + c] * s.qdd[c];
}

Energy AugmentedLagrangian::energy() {
  const MotionState& s = state_;
  Energy e;
  mass_at(s.q);
  Vec mv(nq_), qnc(nq_);
  mass_times(s.qd, mv);
  e.kinetic = 0.5 * s.qd.dot(mv);
  potential_.run(s.q.data(), nullptr, s.t, model_.params().data(), &e.potential);
  nonconservative_.run(s.q.data(), s.qd.data(), s.t, model_.params().data(), qnc.data());
  e.power = s.qd.dot(qnc) + constraint_power_;
  return e;
}

double AugmentedLagrangian::activity(const Energy& /*e*/) {
  const MotionState& s = state_;
  const double* params = model_.params().data();
  Vec applied(nq_), qnc(nq_);
  applied_.run(s.q.data(), s.qd.data(), s.t, params, applied.data());
  nonconservative_.run(s.q.data(), s.qd.data(), s.t, params, qnc.data());
  // Q^A = -V_q + Q^nc: the potential's forces are Q^A - Q^nc.
  return s.qd.cwiseProduct(qnc).cwiseAbs().sum() +
         s.qd.cwiseProduct(applied - qnc).cwiseAbs().sum() + std::abs(constraint_power_);
}

// Bayo and Ledesma's mass-orthogonal projections: q = argmin |q - q*|_M on Phi(q, t) = 0 (Newton
// on the constraints, each step the augmented Lagrangian solution of the linearized problem),
// then qd = argmin |qd - qd*|_M on Phi_q qd = nu at that q.
bool AugmentedLagrangian::project(double t, const double* y, double* correction) {
  if (!check_input(t, y)) return false;
  const Vec target = Vec::Map(y, nq_), rate = Vec::Map(y + nq_, nq_);
  Vec q = target, dq(nq_), mu, f(nq_);
  mass_at(target);
  double last = std::numeric_limits<double>::infinity();
  for (int it = 0; it < kPositionIterations; ++it) {
    if (!jacobian_at(q, t)) return fail(MotionFailure::kNonFinite, "a constraint is not finite");
    if (phi_.cwiseQuotient(row_scale_).cwiseAbs().maxCoeff() <= 1e-15 * (1 + it)) break;
    if (!factor()) return false;
    mass_times(target - q, f);
    solve_constrained(f, -phi_, 1.0, dq, mu);
    q += dq;
    const double step = dq.cwiseQuotient(scale_).cwiseAbs().maxCoeff();
    if (!(step < last) || step <= 1e-15) break;  // converged, or at the rounding floor
    last = step;
  }
  if (!jacobian_at(q, t)) return fail(MotionFailure::kNonFinite, "a constraint is not finite");
  mass_at(q);
  if (!factor()) return false;
  Vec qd(nq_);
  mass_times(rate, f);
  solve_constrained(f, nu_, 1 / tau_, qd, mu);
  if (!q.allFinite() || !qd.allFinite())
    return fail(MotionFailure::kNonFinite, "the projection onto the constraints is not finite");
  for (int k = 0; k < nq_; ++k) {
    correction[k] = q[k] - target[k];
    correction[nq_ + k] = qd[k] - rate[k];
  }
  // The next step's evaluations start from the multipliers at the projected state (on the
  // factorization there): one start for all the step's evaluations, whatever they perturb.
  MotionState projected;
  projected.t = t;
  projected.q = q;
  projected.qd = qd;
  const double power = constraint_power_;
  Vec lambda;
  if (accelerations(projected, lambda)) lambda_start_ = lambda;
  constraint_power_ = power;  // energy() stays at state()
  return true;
}

// The local error estimate projected as the state was, each half by the linear projection at
// the projected position (q's onto Phi_q dq = 0, qd's onto Phi_q dqd = 0, mass-orthogonally):
// near a singular position a position error along a direction that is about to become free
// makes, through the velocity constraint, a velocity error amplified by the rate at which
// Phi_q loses rank, at the level of the nonlinear solver's tolerance; it is removed here with
// the other components the projection removes, rather than failing the error test for ever.
bool AugmentedLagrangian::project_error(double /*t*/, double* error) {
  Vec e(nq_), h, x, mu;
  for (int half = 0; half < 2; ++half) {
    e = Vec::Map(error + half * nq_, nq_);
    j_.times(e, h);
    h = -h;
    solve_constrained(Vec::Zero(nq_), h, 0.0, x, mu);
    e += x;
    if (!e.allFinite()) return false;
    Vec::Map(error + half * nq_, nq_) = e;
  }
  return true;
}

}  // namespace

std::unique_ptr<MotionFormulation> augmented_formulation(const CompiledModel& model,
                                                         const ForceModel& forces, double t0,
                                                         const AugmentedSettings& settings) {
  return std::make_unique<AugmentedLagrangian>(model, forces, t0, settings);
}

std::unique_ptr<MotionFormulation> augmented_formulation(const CompiledModel& model,
                                                         const ForceModel& forces, double t0) {
  return augmented_formulation(model, forces, t0, AugmentedSettings{});
}

}  // namespace kinegen::codegen
