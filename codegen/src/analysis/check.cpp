#include "kinegen/codegen/analysis/check.hpp"

#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <random>
#include <sstream>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/reference.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/base/interrupt.hpp"
#include "kinegen/codegen/model/table.hpp"

namespace kinegen::codegen {

namespace {

using Complex = std::complex<double>;
using Eigen::MatrixXd;
using Eigen::VectorXd;

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kComplexStep = 1e-30;
constexpr double kTwoPi = 6.283185307179586476925286766559;

// The bounds, on |candidate - truth| / max(1, largest |truth| in the block). `growth` is the
// largest max(s_k, |q_k|) / s_k over the samples (s_k the length scale for x and y, 1 rad for
// angles, 1 for t): how far inputs have grown beyond the mechanism's own size, e.g. angles
// after many turns. Rounding in Phi and its derivatives is then up to eps * growth relative
// (terms like phi_i - omega t carry the size of the angle), and the constants below cover
// the number of rounded operations per entry (tens) and the ratio of term size to block size.
//
// (a) Complex step: no subtractive cancellation, Im f(x + i h) / h with h = 1e-30 is f'(x)
//     with the rounding of evaluating f once: C eps growth.
constexpr double kComplexStepFactor = 32;
// (b) Central differences, step h = s cbrt(eps growth) (first) or (eps growth)^(1/4)
//     (second, along (qd, 1)): truncation h^2 f'''/6 (h^2 f''''/12) balances rounding
//     eps growth |f| / h (/ h^2), so both are of order (eps growth)^(2/3) ((eps growth)^(1/2))
//     times derivatives of Phi in units of s, which are O(1) to O(10) for the examples; the
//     factor leaves room for mechanisms whose Phi bends more sharply.
constexpr double kFirstDifferenceFactor = 100;
constexpr double kSecondDifferenceFactor = 100;
// (c) CLN: the symbolic expression at the same (exact) double inputs in `digits` digits,
//     rounded once, is the correctly rounded value to within 10^-digits; the double program
//     differs from it only by its own roundings: per output a sum of at most tens of rounded
//     products of values no larger than a few times the block (Higham: gamma_n sum |terms|),
//     hence C eps growth with the same C as (a).
constexpr double kClnFactor = 32;

struct Accumulator {
  CheckRow row;
  double scale = 1;
  void add(double candidate, double truth) {
    row.max_abs = std::max(row.max_abs, std::abs(candidate - truth));
    scale = std::max(scale, std::abs(truth));
    row.max_rel = row.max_abs / scale;
  }
};

struct Sample {
  VectorXd q, qd;
  double t;
};

// Near q0: lengths by a tenth of the mechanism's size, angles by up to half a radian, then
// every angle turned `turns` times; qd of the coordinates' sizes per unit time. `growth`: the
// largest max(s_k, |q_k|) / s_k (and |t|) over them, for the bounds.
std::vector<Sample> draw_samples(const CompiledModel& model, const CheckOptions& options,
                                 double& growth) {
  const int nq = model.nq();
  const auto& sym = model.symbolic();
  const auto size_of = [&](int k) { return sym.coordinate_scales[k]; };
  const auto is_angle = [&](int k) { return sym.coordinate_kinds[k] == CoordinateKind::kAngle; };
  std::mt19937 rng(options.seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const VectorXd q0 = model.q0();
  std::vector<Sample> samples;
  growth = 1;
  const TableCoverage coverage = table_coverage(model.mechanism());
  constexpr double kInf = std::numeric_limits<double>::infinity();
  for (int s = 0; s < options.samples; ++s) {
    Sample x{VectorXd(nq), VectorXd(nq), 0};
    for (int k = 0; k < nq; ++k) {
      x.q[k] = q0[k] + (is_angle(k) ? 0.5 : 0.1) * size_of(k) * unit(rng);
      if (is_angle(k)) x.q[k] += kTwoPi * options.turns;
      x.qd[k] = size_of(k) * unit(rng);
      growth = std::max(growth, std::abs(x.q[k]) / size_of(k));
    }
    x.t = options.t + unit(rng);
    // A table holds only its range: t inside it, clear of its ends for the central
    // differences.
    if (coverage.lo > -kInf || coverage.hi < kInf)
      x.t = coverage.lo + (coverage.hi - coverage.lo) * (0.5 + 0.4 * unit(rng));
    growth = std::max(growth, std::abs(x.t));
    samples.push_back(x);
  }
  return samples;
}

// The candidate's phi_q, nu and gamma at each sample against the complex step, central
// differences and CLN, one accumulator per function and method.
class DerivativeChecker {
 public:
  DerivativeChecker(const CompiledModel& model, const CheckOptions& options, double growth)
      : model_(model),
        nq_(model.nq()),
        nc_(model.nc()),
        nnz_(static_cast<int>(model.programs().jac_rows.size())),
        real_(model),
        cplx_(model),
        exact_(model, options.digits),
        cand_(options.candidate),
        growth_(growth),
        f_(nc_),
        fp_(nc_),
        fm_(nc_),
        nu_(nc_),
        gamma_(nc_),
        jac_values_(nnz_),
        qc_(nq_),
        fc_(nc_),
        nuc_(nc_),
        jac_(nc_, nq_),
        jacc_(nc_, nq_) {
    // The values under test: the candidate's where given, else the model's program.
    if (!cand_.phi_q_values)
      cand_.phi_q_values = [this](const double* q, double t, double* out) {
        real_.phi_q_values(q, t, out);
      };
    if (!cand_.nu)
      cand_.nu = [this](const double* q, double t, double* out) { real_.nu(q, t, out); };
    if (!cand_.gamma)
      cand_.gamma = [this](const double* q, const double* qd, double t, double* out) {
        real_.gamma(q, qd, t, out);
      };
    const double cs_bound = kComplexStepFactor * kEps * growth;
    const double fd1_bound = kFirstDifferenceFactor * std::pow(kEps * growth, 2.0 / 3.0);
    const double fd2_bound = kSecondDifferenceFactor * std::sqrt(kEps * growth);
    const double cln_bound = kClnFactor * kEps * growth;
    const std::string cln = "cln-" + std::to_string(options.digits);
    jac_cs_ = {{"phi_q", "complex-step", 0, 0, cs_bound}};
    jac_fd_ = {{"phi_q", "central-difference", 0, 0, fd1_bound}};
    jac_hp_ = {{"phi_q", cln, 0, 0, cln_bound}};
    nu_cs_ = {{"nu", "complex-step", 0, 0, cs_bound}};
    nu_fd_ = {{"nu", "central-difference", 0, 0, fd1_bound}};
    nu_hp_ = {{"nu", cln, 0, 0, cln_bound}};
    gamma_cs_ = {{"gamma", "complex-step", 0, 0, cs_bound}};
    gamma_fd_ = {{"gamma", "central-difference", 0, 0, fd2_bound}};
    gamma_hp_ = {{"gamma", cln, 0, 0, cln_bound}};
  }

  void check(const Sample& x) {
    const auto& rows = model_.programs().jac_rows;
    const auto& cols = model_.programs().jac_cols;
    cand_.phi_q_values(x.q.data(), x.t, jac_values_.data());
    jac_.setZero();
    for (int e = 0; e < nnz_; ++e) jac_(rows[e], cols[e]) = jac_values_[e];
    cand_.nu(x.q.data(), x.t, nu_.data());
    cand_.gamma(x.q.data(), x.qd.data(), x.t, gamma_.data());
    check_phi_q(x.q, x.t);
    check_nu(x.q, x.t);
    check_gamma(x.q, x.qd, x.t);
    check_cln(x.q, x.qd, x.t);
  }

  std::vector<CheckRow> rows() const {
    return {jac_cs_.row, jac_fd_.row,   jac_hp_.row,   nu_cs_.row,   nu_fd_.row,
            nu_hp_.row,  gamma_cs_.row, gamma_fd_.row, gamma_hp_.row};
  }

 private:
  double size_of(int k) const { return model_.symbolic().coordinate_scales[k]; }

  // Phi_q, column by column (every entry, so a structural zero that is not one shows).
  void check_phi_q(const VectorXd& q, double t) {
    for (int k = 0; k < nq_; ++k) {
      qc_ = q.cast<Complex>();
      qc_[k] += Complex(0, kComplexStep);
      cplx_.phi(qc_.data(), Complex(t), fc_.data());
      const double s = size_of(k);
      const double h = s * std::cbrt(kEps * std::max(s, std::abs(q[k])) / s);
      VectorXd qp = q, qm = q;
      qp[k] += h;
      qm[k] -= h;
      real_.phi(qp.data(), t, fp_.data());
      real_.phi(qm.data(), t, fm_.data());
      for (int r = 0; r < nc_; ++r) {
        jac_cs_.add(jac_(r, k), fc_[r].imag() / kComplexStep);
        // The steps actually taken, after rounding q +- h.
        jac_fd_.add(jac_(r, k), (fp_[r] - fm_[r]) / (qp[k] - qm[k]));
      }
    }
  }

  // nu = -Phi_t.
  void check_nu(const VectorXd& q, double t) {
    cplx_.phi(q.cast<Complex>().eval().data(), Complex(t, kComplexStep), fc_.data());
    const double h = std::cbrt(kEps * std::max(1.0, std::abs(t)));
    const double tp = t + h, tm = t - h;
    real_.phi(q.data(), tp, fp_.data());
    real_.phi(q.data(), tm, fm_.data());
    for (int r = 0; r < nc_; ++r) {
      nu_cs_.add(nu_[r], -fc_[r].imag() / kComplexStep);
      nu_fd_.add(nu_[r], -(fp_[r] - fm_[r]) / (tp - tm));
    }
  }

  // gamma = -d2/ds2 Phi(q + s qd, t + s) at s = 0. The complex step differentiates
  // dPhi/ds = Phi_q qd - nu once more; the central difference takes Phi twice.
  void check_gamma(const VectorXd& q, const VectorXd& qd, double t) {
    qc_ = q.cast<Complex>() + Complex(0, kComplexStep) * qd.cast<Complex>();
    const Complex tc(t, kComplexStep);
    jacc_.setZero();
    cplx_.jacobian(qc_.data(), tc, jacc_);
    cplx_.nu(qc_.data(), tc, nuc_.data());
    const Eigen::VectorXcd dphi_ds = jacc_ * qd.cast<Complex>() - nuc_;
    const double h = std::pow(kEps * growth_, 0.25);
    real_.phi(q.data(), t, f_.data());
    const VectorXd qp = q + h * qd, qm = q - h * qd;
    real_.phi(qp.data(), t + h, fp_.data());
    real_.phi(qm.data(), t - h, fm_.data());
    for (int r = 0; r < nc_; ++r) {
      gamma_cs_.add(gamma_[r], -dphi_ds[r].imag() / kComplexStep);
      gamma_fd_.add(gamma_[r], -(fp_[r] - 2 * f_[r] + fm_[r]) / (h * h));
    }
  }

  // The symbolic expressions themselves, in CLN arithmetic at the same (exact) inputs.
  void check_cln(const VectorXd& q, const VectorXd& qd, double t) {
    HighPrecisionEvaluator::Vector qx, qdx;
    for (int k = 0; k < nq_; ++k) {
      qx.push_back(exact_numeric(q[k]));
      qdx.push_back(exact_numeric(qd[k]));
    }
    const GiNaC::numeric tx = exact_numeric(t);
    const auto jac_ref = exact_.phi_q_values(qx, tx);
    for (int e = 0; e < nnz_; ++e) jac_hp_.add(jac_values_[e], jac_ref[e].to_double());
    const auto nu_ref = exact_.nu(qx, tx);
    for (int r = 0; r < nc_; ++r) nu_hp_.add(nu_[r], nu_ref[r].to_double());
    const auto gamma_ref = exact_.gamma(qx, qdx, tx);
    for (int r = 0; r < nc_; ++r) gamma_hp_.add(gamma_[r], gamma_ref[r].to_double());
  }

  const CompiledModel& model_;
  const int nq_, nc_, nnz_;
  ModelEvaluator<double> real_;
  ModelEvaluator<Complex> cplx_;
  HighPrecisionEvaluator exact_;
  CheckCandidate cand_;
  const double growth_;
  Accumulator jac_cs_, jac_fd_, jac_hp_, nu_cs_, nu_fd_, nu_hp_, gamma_cs_, gamma_fd_, gamma_hp_;
  VectorXd f_, fp_, fm_, nu_, gamma_, jac_values_;
  Eigen::VectorXcd qc_, fc_, nuc_;
  MatrixXd jac_;
  Eigen::MatrixXcd jacc_;
};

}  // namespace

std::vector<CheckRow> check_derivatives(const CompiledModel& model, const CheckOptions& options) {
  if (options.samples < 1) throw UsageError("--samples must be at least 1");
  if (!std::isfinite(options.turns) || !std::isfinite(options.t))
    throw UsageError("--turns and --t must be finite");
  if (options.digits < kMinReferenceDigits || options.digits > kMaxReferenceDigits)
    throw UsageError("--digits must be between " + std::to_string(kMinReferenceDigits) + " and " +
                     std::to_string(kMaxReferenceDigits));
  require_kept_rows("check", options.samples, static_cast<std::size_t>(model.nq()), "--samples");
  double growth = 1;
  const std::vector<Sample> samples = draw_samples(model, options, growth);
  DerivativeChecker checker(model, options, growth);
  for (const Sample& x : samples) {
    interruption_point();
    checker.check(x);
  }
  return checker.rows();
}

std::string jacobian_structure(const CompiledModel& model) {
  const auto& symbolic = model.symbolic();
  const auto& syms = model.symbols();
  std::ostringstream os;
  os << "Phi_q structure (" << model.nc() << " x " << model.nq() << ", " << symbolic.phi_q.size()
     << " structural non-zeros; '.' zero, 'c' constant, 'v' varying):\n";
  std::vector<std::string> grid(model.nc(), std::string(model.nq(), '.'));
  int constants = 0;
  for (const auto& e : symbolic.phi_q) {
    bool varying = false;
    for (int k = 0; k < model.nq(); ++k) varying = varying || e.value.has(syms.q(k));
    varying = varying || e.value.has(syms.t());
    grid[e.row][e.col] = varying ? 'v' : 'c';
    constants += !varying;
  }
  os << "      ";
  for (int k = 0; k < model.nq(); ++k) os << (k % 10);
  os << "\n";
  for (int r = 0; r < model.nc(); ++r) {
    char label[16];
    std::snprintf(label, sizeof label, "%4d  ", r);
    os << label << grid[r] << "  " << model.row_label(r) << "\n";
  }
  os << constants << " constant, " << symbolic.phi_q.size() - constants << " varying\n";
  return os.str();
}

}  // namespace kinegen::codegen
