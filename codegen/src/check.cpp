#include "kinegen/codegen/check.hpp"

#include <cmath>
#include <complex>
#include <limits>
#include <random>
#include <sstream>

namespace kinegen::codegen {

namespace {

using Complex = std::complex<double>;
using Eigen::MatrixXd;
using Eigen::VectorXd;

// Bounds on the normalized difference. Complex step is exact to rounding; central differences
// carry truncation and cancellation error of order eps^(2/3) (first) and eps^(1/2) (second).
constexpr double kComplexStepBound = 1e-11;
constexpr double kFirstDifferenceBound = 1e-6;
constexpr double kSecondDifferenceBound = 1e-4;
constexpr double kComplexStep = 1e-30;

struct Accumulator {
  CheckRow row;
  double scale = 1;
  void add(double symbolic, double numeric) {
    row.max_abs = std::max(row.max_abs, std::abs(symbolic - numeric));
    scale = std::max(scale, std::abs(numeric));
    row.max_rel = row.max_abs / scale;
  }
};

}  // namespace

std::vector<CheckRow> check_derivatives(const CompiledModel& model, const CheckOptions& options) {
  const int nq = model.nq(), nc = model.nc();
  const double length = model.symbolic().length_scale;
  ModelEvaluator<double> real(model);
  ModelEvaluator<Complex> cplx(model);
  std::mt19937 rng(options.seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);

  Accumulator jac_cs{{"phi_q", "complex-step", 0, 0, kComplexStepBound}};
  Accumulator jac_fd{{"phi_q", "central-difference", 0, 0, kFirstDifferenceBound}};
  Accumulator nu_cs{{"nu", "complex-step", 0, 0, kComplexStepBound}};
  Accumulator nu_fd{{"nu", "central-difference", 0, 0, kFirstDifferenceBound}};
  Accumulator gamma_cs{{"gamma", "complex-step", 0, 0, kComplexStepBound}};
  Accumulator gamma_fd{{"gamma", "central-difference", 0, 0, kSecondDifferenceBound}};

  const double eps = std::numeric_limits<double>::epsilon();
  const VectorXd q0 = model.q0();
  VectorXd q(nq), qd(nq), f(nc), fp(nc), fm(nc), nu(nc), gamma(nc);
  Eigen::VectorXcd qc(nq), fc(nc), nuc(nc);
  MatrixXd jac = MatrixXd::Zero(nc, nq);
  Eigen::MatrixXcd jacc = Eigen::MatrixXcd::Zero(nc, nq);

  for (int s = 0; s < options.samples; ++s) {
    // Near q0: lengths by a tenth of the mechanism's size, angles by up to half a radian.
    for (int k = 0; k < nq; ++k) {
      const double size = k % 3 == 2 ? 1.0 : length;
      q[k] = q0[k] + (k % 3 == 2 ? 0.5 : 0.1) * size * unit(rng);
      qd[k] = size * unit(rng);
    }
    const double t = options.t + unit(rng);
    jac.setZero();
    real.jacobian(q.data(), t, jac);
    real.nu(q.data(), t, nu.data());
    real.gamma(q.data(), qd.data(), t, gamma.data());

    // Phi_q, column by column.
    for (int k = 0; k < nq; ++k) {
      qc = q.cast<Complex>();
      qc[k] += Complex(0, kComplexStep);
      cplx.phi(qc.data(), Complex(t), fc.data());
      const double h = std::cbrt(eps) * std::max(k % 3 == 2 ? 1.0 : length, std::abs(q[k]));
      VectorXd qp = q, qm = q;
      qp[k] += h;
      qm[k] -= h;
      real.phi(qp.data(), t, fp.data());
      real.phi(qm.data(), t, fm.data());
      for (int r = 0; r < nc; ++r) {
        jac_cs.add(jac(r, k), fc[r].imag() / kComplexStep);
        jac_fd.add(jac(r, k), (fp[r] - fm[r]) / ((qp[k] - q[k]) + (q[k] - qm[k])));
      }
    }
    // nu = -Phi_t.
    {
      cplx.phi(q.cast<Complex>().eval().data(), Complex(t, kComplexStep), fc.data());
      const double h = std::cbrt(eps) * std::max(1.0, std::abs(t));
      real.phi(q.data(), t + h, fp.data());
      real.phi(q.data(), t - h, fm.data());
      for (int r = 0; r < nc; ++r) {
        nu_cs.add(nu[r], -fc[r].imag() / kComplexStep);
        nu_fd.add(nu[r], -(fp[r] - fm[r]) / ((t + h) - (t - h)));
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
      const double h = std::pow(eps, 0.25);
      real.phi(q.data(), t, f.data());
      const VectorXd qp = q + h * qd, qm = q - h * qd;
      real.phi(qp.data(), t + h, fp.data());
      real.phi(qm.data(), t - h, fm.data());
      for (int r = 0; r < nc; ++r) {
        gamma_cs.add(gamma[r], -dphi_ds[r].imag() / kComplexStep);
        gamma_fd.add(gamma[r], -(fp[r] - 2 * f[r] + fm[r]) / (h * h));
      }
    }
  }
  return {jac_cs.row, jac_fd.row, nu_cs.row, nu_fd.row, gamma_cs.row, gamma_fd.row};
}

std::string jacobian_structure(const CompiledModel& model) {
  const auto& symbolic = model.symbolic();
  const auto& syms = model.symbols();
  std::ostringstream os;
  os << "Phi_q structure (" << model.nc() << " x " << model.nq() << ", "
     << symbolic.phi_q.size() << " structural non-zeros; '.' zero, 'c' constant, 'v' varying):\n";
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
