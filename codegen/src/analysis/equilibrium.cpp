// Equilibrium and the reduced stiffness (see analysis/equilibrium.hpp).
#include "kinegen/codegen/analysis/equilibrium.hpp"

#include <cmath>
#include <cstdio>

#include "kinegen/codegen/base/format.hpp"

namespace kinegen::codegen {

namespace {

// An eigenvalue of K_z v = lambda M_z v below this fraction of the largest, or of the forces'
// own size, is zero stiffness (a neutral direction): K_z's rounding is far below it.
constexpr double kNeutral = 1e-9;
// Newton has converged when its step is below this (scaled: radians, length scales) and the
// linear model explains zdd (so a singular K_z does not hide a force it cannot balance).
constexpr double kStep = 1e-10;

std::string describe(const Eigen::VectorXd& v, const std::vector<std::string>& names) {
  const double largest = v.cwiseAbs().maxCoeff();
  std::string out;
  int terms = 0;
  for (Eigen::Index k = 0; k < v.size(); ++k)
    if (std::abs(v[k]) >= 1e-3 * largest) ++terms;
  for (Eigen::Index k = 0; k < v.size(); ++k) {
    if (std::abs(v[k]) < 1e-3 * largest) continue;
    if (terms == 1) return names[k];
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.3g ", std::abs(v[k]));
    out += (out.empty() ? (v[k] < 0 ? "-" : "") : (v[k] < 0 ? " - " : " + ")) + std::string(buf) +
           names[k];
  }
  return out;
}

std::vector<std::string> free_item_names(const Mechanism& m) {
  std::vector<std::string> names;
  for (int d : m.free_drivers()) names.push_back(m.drivers[d].name);
  return names;
}

}  // namespace

const char* to_string(Stability s) {
  return s == Stability::kStable ? "stable" : s == Stability::kUnstable ? "unstable" : "neutral";
}

ReducedStiffness reduced_stiffness(const Linearizer& lin, const MotionState& state,
                                   const Eigen::MatrixXd& d_z, const Eigen::MatrixXd& d_zd) {
  ReducedStiffness r;
  r.mass = lin.reduced_mass(state);
  r.stiffness = -r.mass * d_z;
  r.damping = -r.mass * d_zd;
  const double size = r.stiffness.cwiseAbs().maxCoeff();
  r.symmetric = (r.stiffness - r.stiffness.transpose()).cwiseAbs().maxCoeff() <= 1e-8 * size;
  const Eigen::MatrixXd sym = (r.stiffness + r.stiffness.transpose()) / 2;
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(sym, r.mass);
  r.eigenvalues = eig.eigenvalues();
  r.directions = eig.eigenvectors();
  // The size of the forces in units of lambda (1/s^2): |B|^T |Q^A| per unit of mass and scale.
  const Eigen::VectorXd s = lin.scales();
  double reference = r.eigenvalues.cwiseAbs().maxCoeff();
  for (Eigen::Index k = 0; k < s.size(); ++k)
    if (r.mass(k, k) > 0)
      reference = std::max(reference, lin.force_terms()[k] / (r.mass(k, k) * s[k]));
  const std::vector<std::string> names = free_item_names(lin.model().mechanism());
  bool negative = false, zero = false;
  for (Eigen::Index k = 0; k < r.eigenvalues.size(); ++k) {
    Eigen::VectorXd v = r.directions.col(k);
    Eigen::Index at = 0;
    v.cwiseAbs().maxCoeff(&at);
    v /= v[at];
    r.directions.col(k) = v;
    if (std::abs(r.eigenvalues[k]) <= kNeutral * reference) {
      zero = true;
      r.neutral.push_back(describe(v, names));
      r.kinds.push_back(Stability::kNeutral);
    } else if (r.eigenvalues[k] < 0) {
      negative = true;
      r.unstable.push_back(describe(v, names));
      r.kinds.push_back(Stability::kUnstable);
    } else {
      r.kinds.push_back(Stability::kStable);
    }
  }
  r.stability = negative ? Stability::kUnstable : zero ? Stability::kNeutral : Stability::kStable;
  return r;
}

namespace {

[[noreturn]] void no_equilibrium(const Linearizer& lin, const OperatingPoint& start,
                                 const OperatingPoint& p, const MotionState& state, int iterations,
                                 const std::string& why) {
  const Mechanism& m = lin.model().mechanism();
  const std::vector<std::string> names = free_item_names(m);
  const Eigen::VectorXd force = lin.reduced_mass(state) * state.zdd;
  std::string from, at, left;
  for (int k = 0; k < lin.nf(); ++k) {
    from += (k ? ", " : "") + names[k] + " = " + format_number(start.z[k]);
    at += (k ? ", " : "") + names[k] + " = " + format_number(p.z[k]);
    left += (k ? ", " : "") + format_estimate(force[k]);
  }
  throw AnalysisError(
      m.source + ": no equilibrium near value0 (" + from + ") at " + format_time(p.t) + ": " + why +
      " after " + std::to_string(iterations) + " Newton steps, at " + at +
      ", the generalized forces B^T Q^A on the free "
      "coordinates are still " +
      left + " (loads that balance in no position near it, or value0 far from one)");
}

}  // namespace

Equilibrium find_equilibrium(Linearizer& lin, OperatingPoint p, int max_iterations) {
  const int nf = lin.nf();
  const Eigen::VectorXd s = lin.scales();
  const auto scaled = [&](const Eigen::VectorXd& v) {
    return nf == 0 ? 0.0 : (v.array() / s.array()).abs().maxCoeff();
  };
  const auto merit = [&](const MotionState& st) {
    return (st.zdd.array() / s.array()).matrix().squaredNorm();
  };
  p.zd.setZero(nf);
  const OperatingPoint start = p;
  Equilibrium e;
  Eigen::MatrixXd d_z, d_zd;
  if (!lin.evaluate(p, e.state, &d_z, &d_zd))
    throw AnalysisError(lin.model().mechanism().source + ": no equilibrium search from value0 at " +
                        format_time(p.t) + ": " + lin.reason());
  double trust = 1;
  bool converged = false;
  int it = 0;
  for (; it < max_iterations && !converged; ++it) {
    const Eigen::VectorXd newton = d_z.completeOrthogonalDecomposition().solve(-e.state.zdd);
    // The linear model must explain zdd: a singular K_z gives a least-squares step that leaves
    // the force it cannot balance.
    const double unexplained =
        newton.allFinite() ? scaled(d_z * newton + e.state.zdd) : scaled(e.state.zdd);
    const bool usable = newton.allFinite() && unexplained <= 0.5 * scaled(e.state.zdd);
    if (e.state.zdd.isZero(0) ||
        (usable && scaled(newton) <= kStep && unexplained <= 1e-6 * scaled(e.state.zdd))) {
      converged = true;
      if (e.state.zdd.isZero(0)) break;
    }
    // A Newton step inside the trust region, else a step along zdd as long as the region.
    bool accepted = false;
    while (!accepted && trust > 1e-12) {
      const bool take_newton = usable && scaled(newton) <= trust;
      const Eigen::VectorXd step =
          take_newton ? newton : Eigen::VectorXd(e.state.zdd * (trust / scaled(e.state.zdd)));
      OperatingPoint trial = p;
      trial.z += step;
      MotionState ts;
      Eigen::MatrixXd tz, tzd;
      // A Newton step must lower |zdd|; a fall is kept while the forces still pull along it
      // (the potential still falls: no equilibrium passed) or |zdd| is lower.
      const bool solved = lin.evaluate(trial, ts, &tz, &tzd);
      const bool falling =
          !take_newton && solved &&
          (ts.zdd.array() / s.array()).matrix().dot((e.state.zdd.array() / s.array()).matrix()) > 0;
      if (solved && (converged || falling || merit(ts) < merit(e.state))) {
        p = trial;
        e.state = ts;
        d_z = tz;
        d_zd = tzd;
        accepted = true;
        if (take_newton) trust = std::min(1.0, std::max(trust, 2 * scaled(step)));
      } else {
        trust = std::min(trust, scaled(step)) / 4;
      }
    }
    if (!accepted) {
      if (converged) break;  // the last step only rounds: z is the equilibrium
      no_equilibrium(lin, start, p, e.state, it, "no step lowers the accelerations");
    }
  }
  if (!converged) no_equilibrium(lin, start, p, e.state, it, "Newton did not converge");
  // The state at the equilibrium (the Linearizer's last evaluation is of a trial).
  if (!lin.evaluate(p, e.state, &d_z, &d_zd))
    throw AnalysisError(lin.model().mechanism().source + ": at the equilibrium: " + lin.reason());
  e.at = p;
  e.iterations = it;
  e.stiffness = reduced_stiffness(lin, e.state, d_z, d_zd);
  e.force = e.stiffness.mass * e.state.zdd;
  return e;
}

}  // namespace kinegen::codegen
