#include "kinegen/codegen/analysis/check.hpp"

#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <random>
#include <sstream>

#include "kinegen/codegen/analysis/reference.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
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

}  // namespace

std::vector<CheckRow> check_derivatives(const CompiledModel& model, const CheckOptions& options) {
  if (options.samples < 1) throw UsageError("--samples must be at least 1");
  if (!std::isfinite(options.turns) || !std::isfinite(options.t))
    throw UsageError("--turns and --t must be finite");
  if (options.digits < kMinReferenceDigits || options.digits > kMaxReferenceDigits)
    throw UsageError("--digits must be between " + std::to_string(kMinReferenceDigits) + " and " +
                     std::to_string(kMaxReferenceDigits));
  const int nq = model.nq(), nc = model.nc();
  const int nnz = static_cast<int>(model.programs().jac_rows.size());
  const auto& sym = model.symbolic();
  const auto size_of = [&](int k) { return sym.coordinate_scales[k]; };
  const auto is_angle = [&](int k) { return sym.coordinate_kinds[k] == CoordinateKind::kAngle; };
  ModelEvaluator<double> real(model);
  ModelEvaluator<Complex> cplx(model);
  HighPrecisionEvaluator exact(model, options.digits);

  // The values under test: the candidate's where given, else the model's program.
  CheckCandidate cand = options.candidate;
  if (!cand.phi_q_values)
    cand.phi_q_values = [&](const double* q, double t, double* out) {
      real.phi_q_values(q, t, out);
    };
  if (!cand.nu) cand.nu = [&](const double* q, double t, double* out) { real.nu(q, t, out); };
  if (!cand.gamma)
    cand.gamma = [&](const double* q, const double* qd, double t, double* out) {
      real.gamma(q, qd, t, out);
    };

  // Near q0: lengths by a tenth of the mechanism's size, angles by up to half a radian, then
  // every angle turned `turns` times; qd of the coordinates' sizes per unit time.
  std::mt19937 rng(options.seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const VectorXd q0 = model.q0();
  std::vector<Sample> samples;
  double growth = 1;
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
    // A table holds only its range (format 6.3): t inside it, clear of its ends for the
    // central differences.
    if (coverage.lo > -kInf || coverage.hi < kInf)
      x.t = coverage.lo + (coverage.hi - coverage.lo) * (0.5 + 0.4 * unit(rng));
    growth = std::max(growth, std::abs(x.t));
    samples.push_back(x);
  }

  const double cs_bound = kComplexStepFactor * kEps * growth;
  const double fd1_bound = kFirstDifferenceFactor * std::pow(kEps * growth, 2.0 / 3.0);
  const double fd2_bound = kSecondDifferenceFactor * std::sqrt(kEps * growth);
  const double cln_bound = kClnFactor * kEps * growth;
  const std::string cln = "cln-" + std::to_string(options.digits);
  Accumulator jac_cs{{"phi_q", "complex-step", 0, 0, cs_bound}};
  Accumulator jac_fd{{"phi_q", "central-difference", 0, 0, fd1_bound}};
  Accumulator jac_hp{{"phi_q", cln, 0, 0, cln_bound}};
  Accumulator nu_cs{{"nu", "complex-step", 0, 0, cs_bound}};
  Accumulator nu_fd{{"nu", "central-difference", 0, 0, fd1_bound}};
  Accumulator nu_hp{{"nu", cln, 0, 0, cln_bound}};
  Accumulator gamma_cs{{"gamma", "complex-step", 0, 0, cs_bound}};
  Accumulator gamma_fd{{"gamma", "central-difference", 0, 0, fd2_bound}};
  Accumulator gamma_hp{{"gamma", cln, 0, 0, cln_bound}};

  const auto& rows = model.programs().jac_rows;
  const auto& cols = model.programs().jac_cols;
  VectorXd f(nc), fp(nc), fm(nc), nu(nc), gamma(nc), jac_values(nnz);
  Eigen::VectorXcd qc(nq), fc(nc), nuc(nc);
  MatrixXd jac(nc, nq);
  Eigen::MatrixXcd jacc(nc, nq);

  for (const Sample& x : samples) {
    const VectorXd& q = x.q;
    const VectorXd& qd = x.qd;
    const double t = x.t;
    cand.phi_q_values(q.data(), t, jac_values.data());
    jac.setZero();
    for (int e = 0; e < nnz; ++e) jac(rows[e], cols[e]) = jac_values[e];
    cand.nu(q.data(), t, nu.data());
    cand.gamma(q.data(), qd.data(), t, gamma.data());

    // Phi_q, column by column (every entry, so a structural zero that is not one shows).
    for (int k = 0; k < nq; ++k) {
      qc = q.cast<Complex>();
      qc[k] += Complex(0, kComplexStep);
      cplx.phi(qc.data(), Complex(t), fc.data());
      const double s = size_of(k);
      const double h = s * std::cbrt(kEps * std::max(s, std::abs(q[k])) / s);
      VectorXd qp = q, qm = q;
      qp[k] += h;
      qm[k] -= h;
      real.phi(qp.data(), t, fp.data());
      real.phi(qm.data(), t, fm.data());
      for (int r = 0; r < nc; ++r) {
        jac_cs.add(jac(r, k), fc[r].imag() / kComplexStep);
        // The steps actually taken, after rounding q +- h.
        jac_fd.add(jac(r, k), (fp[r] - fm[r]) / (qp[k] - qm[k]));
      }
    }
    // nu = -Phi_t.
    {
      cplx.phi(q.cast<Complex>().eval().data(), Complex(t, kComplexStep), fc.data());
      const double h = std::cbrt(kEps * std::max(1.0, std::abs(t)));
      const double tp = t + h, tm = t - h;
      real.phi(q.data(), tp, fp.data());
      real.phi(q.data(), tm, fm.data());
      for (int r = 0; r < nc; ++r) {
        nu_cs.add(nu[r], -fc[r].imag() / kComplexStep);
        nu_fd.add(nu[r], -(fp[r] - fm[r]) / (tp - tm));
      }
    }
    // gamma = -d2/ds2 Phi(q + s qd, t + s) at s = 0. The complex step differentiates
    // dPhi/ds = Phi_q qd - nu once more; the central difference takes Phi twice.
    {
      qc = q.cast<Complex>() + Complex(0, kComplexStep) * qd.cast<Complex>();
      const Complex tc(t, kComplexStep);
      jacc.setZero();
      cplx.jacobian(qc.data(), tc, jacc);
      cplx.nu(qc.data(), tc, nuc.data());
      const Eigen::VectorXcd dphi_ds = jacc * qd.cast<Complex>() - nuc;
      const double h = std::pow(kEps * growth, 0.25);
      real.phi(q.data(), t, f.data());
      const VectorXd qp = q + h * qd, qm = q - h * qd;
      real.phi(qp.data(), t + h, fp.data());
      real.phi(qm.data(), t - h, fm.data());
      for (int r = 0; r < nc; ++r) {
        gamma_cs.add(gamma[r], -dphi_ds[r].imag() / kComplexStep);
        gamma_fd.add(gamma[r], -(fp[r] - 2 * f[r] + fm[r]) / (h * h));
      }
    }
    // The symbolic expressions themselves, in CLN arithmetic at the same (exact) inputs.
    {
      HighPrecisionEvaluator::Vector qx, qdx;
      for (int k = 0; k < nq; ++k) {
        qx.push_back(exact_numeric(q[k]));
        qdx.push_back(exact_numeric(qd[k]));
      }
      const GiNaC::numeric tx = exact_numeric(t);
      const auto jac_ref = exact.phi_q_values(qx, tx);
      for (int e = 0; e < nnz; ++e) jac_hp.add(jac_values[e], jac_ref[e].to_double());
      const auto nu_ref = exact.nu(qx, tx);
      for (int r = 0; r < nc; ++r) nu_hp.add(nu[r], nu_ref[r].to_double());
      const auto gamma_ref = exact.gamma(qx, qdx, tx);
      for (int r = 0; r < nc; ++r) gamma_hp.add(gamma[r], gamma_ref[r].to_double());
    }
  }
  return {jac_cs.row, jac_fd.row,   jac_hp.row,   nu_cs.row,   nu_fd.row,
          nu_hp.row,  gamma_cs.row, gamma_fd.row, gamma_hp.row};
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
