// Small oscillations about a state: natural frequencies, damping ratios and mode shapes (see
// analysis/equilibrium.hpp).
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>

#include "kinegen/codegen/analysis/equilibrium.hpp"
#include "kinegen/codegen/base/format.hpp"

namespace kinegen::codegen {

namespace {

constexpr double kTwoPi = 6.283185307179586476925286766559;

// dz scaled to a largest component of 1 (positive), and dq = B dz.
void set_shape(Mode& mode, Eigen::VectorXd dz, const Eigen::MatrixXd& b) {
  Eigen::Index at = 0;
  dz.cwiseAbs().maxCoeff(&at);
  if (dz[at] != 0) dz /= dz[at];
  mode.dz = dz;
  mode.dq = b * dz;
}

// Without damping: K_z v = lambda M_z v (the stiffness report's eigenpairs).
std::vector<Mode> undamped_modes(const ReducedStiffness& r, const Eigen::MatrixXd& b) {
  std::vector<Mode> modes;
  for (Eigen::Index k = 0; k < r.eigenvalues.size(); ++k) {
    Mode mode;
    mode.eigenvalue = r.eigenvalues[k];
    mode.kind = r.kinds[k];
    if (mode.kind == Stability::kStable)
      mode.frequency = mode.damped_frequency = std::sqrt(mode.eigenvalue) / kTwoPi;
    set_shape(mode, r.directions.col(k), b);
    modes.push_back(std::move(mode));
  }
  return modes;
}

// With damping: the state matrix's eigenvalues s = -zeta w +- i w sqrt(1 - zeta^2), one mode
// per pair (Im s > 0) or per real s. A mode grows (unstable) where Re s exceeds the eigenvalues'
// rounding (64 eps |A|); it is neutral only where K_z has zero stiffness (r.kinds): each such
// direction puts one root at s = 0, the real roots nearest 0, whatever the damping's size.
std::vector<Mode> damped_modes(const ReducedStiffness& r, const Eigen::MatrixXd& b) {
  const Eigen::Index nf = r.mass.rows();
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(2 * nf, 2 * nf);
  const Eigen::LDLT<Eigen::MatrixXd> m(r.mass);
  a.topRightCorner(nf, nf).setIdentity();
  a.bottomLeftCorner(nf, nf) = -m.solve(r.stiffness);
  a.bottomRightCorner(nf, nf) = -m.solve(r.damping);
  Eigen::EigenSolver<Eigen::MatrixXd> eig(a);
  const double rounding = 64 * std::numeric_limits<double>::epsilon() * a.cwiseAbs().maxCoeff() *
                          static_cast<double>(2 * nf);
  // The real roots' indices by |s|: the first `zero` of them are the neutral directions.
  const auto zero =
      static_cast<std::size_t>(std::count(r.kinds.begin(), r.kinds.end(), Stability::kNeutral));
  std::vector<Eigen::Index> real;
  for (Eigen::Index k = 0; k < 2 * nf; ++k)
    if (std::abs(eig.eigenvalues()[k].imag()) <= rounding) real.push_back(k);
  std::stable_sort(real.begin(), real.end(), [&](Eigen::Index x, Eigen::Index y) {
    return std::abs(eig.eigenvalues()[x]) < std::abs(eig.eigenvalues()[y]);
  });
  std::vector<Mode> modes;
  for (Eigen::Index k = 0; k < 2 * nf; ++k) {
    const std::complex<double> s = eig.eigenvalues()[k];
    const auto rank = std::find(real.begin(), real.end(), k);
    if (rank == real.end() && s.imag() < 0) continue;  // the pair's other half
    Mode mode;
    const double w = std::abs(s);
    Eigen::VectorXcd v = eig.eigenvectors().col(k).head(nf);
    Eigen::Index at = 0;
    v.cwiseAbs().maxCoeff(&at);
    v /= v[at];  // the largest component real: the shape is its real part
    mode.kind = s.real() > rounding ? Stability::kUnstable : Stability::kStable;
    if (rank == real.end()) {
      mode.frequency = w / kTwoPi;
      mode.damped_frequency = s.imag() / kTwoPi;
      mode.damping_ratio = -s.real() / w;
      mode.eigenvalue = w * w;
    } else {
      // Real: a decaying (overdamped), growing or neutral motion, no oscillation.
      mode.eigenvalue = s.real();
      mode.damping_ratio = s.real() < 0 ? 1 : 0;
      if (static_cast<std::size_t>(rank - real.begin()) < zero) {
        mode.kind = Stability::kNeutral;
        mode.eigenvalue = mode.damping_ratio = 0;
      }
    }
    set_shape(mode, v.real(), b);
    modes.push_back(std::move(mode));
  }
  return modes;
}

}  // namespace

ModalAnalysis modal_analysis(Linearizer& lin, OperatingPoint p) {
  p.zd.setZero(lin.nf());
  ModalAnalysis out;
  Eigen::MatrixXd d_z, d_zd;
  if (!lin.evaluate(p, out.state, &d_z, &d_zd))
    throw AnalysisError(lin.model().mechanism().source + ": no modes at " + format_time(p.t) +
                        ": " + lin.reason());
  out.at = p;
  out.stiffness = reduced_stiffness(lin, out.state, d_z, d_zd);
  out.force = out.stiffness.mass * out.state.zdd;
  const ReducedStiffness& r = out.stiffness;
  out.damped = r.damping.cwiseAbs().maxCoeff() > 0;
  const Eigen::MatrixXd& b = lin.dynamics().b();
  out.modes = out.damped ? damped_modes(r, b) : undamped_modes(r, b);
  std::stable_sort(out.modes.begin(), out.modes.end(),
                   [](const Mode& x, const Mode& y) { return x.frequency < y.frequency; });
  // The verdict of the modes: one that grows makes the point unstable (negative damping does,
  // with a positive K_z), one of zero stiffness neutral.
  const auto any = [&](Stability kind) {
    return std::any_of(out.modes.begin(), out.modes.end(),
                       [&](const Mode& x) { return x.kind == kind; });
  };
  out.stability = any(Stability::kUnstable)  ? Stability::kUnstable
                  : any(Stability::kNeutral) ? Stability::kNeutral
                                             : Stability::kStable;
  return out;
}

}  // namespace kinegen::codegen
