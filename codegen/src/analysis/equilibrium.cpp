// Equilibrium and the reduced stiffness (see analysis/equilibrium.hpp).
#include "kinegen/codegen/analysis/equilibrium.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "kinegen/codegen/base/format.hpp"

namespace kinegen::codegen {

namespace {

// An eigenvalue of K_z v = lambda M_z v below this fraction of the largest, or of the forces'
// own size, is zero stiffness (a neutral direction): K_z's rounding is far below it.
constexpr double kNeutral = 1e-9;

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

Eigen::VectorXd rest_bound(const Linearizer& lin, const MotionState& state,
                           const Eigen::MatrixXd& mass, const Eigen::MatrixXd& stiffness) {
  const double nq = lin.model().nq();
  const Eigen::VectorXd size = state.z.cwiseAbs().cwiseMax(lin.scales());
  return 16 * nq * std::numeric_limits<double>::epsilon() *
         (lin.force_terms() + stiffness.cwiseAbs() * size + mass.cwiseAbs() * state.zdd.cwiseAbs());
}

namespace {

std::string z_text(const Linearizer& lin, const Eigen::VectorXd& z) {
  const std::vector<std::string> names = free_item_names(lin.model().mechanism());
  std::string out;
  for (int k = 0; k < lin.nf(); ++k)
    out += (k ? ", " : "") + names[k] + " = " + format_number(z[k]);
  return out;
}

[[noreturn]] void no_equilibrium(const Linearizer& lin, const OperatingPoint& start,
                                 const OperatingPoint& p, const MotionState& state,
                                 const Eigen::MatrixXd& d_z, int iterations,
                                 const std::string& why) {
  const Mechanism& m = lin.model().mechanism();
  const Eigen::MatrixXd mass = lin.reduced_mass(state);
  const Eigen::VectorXd force = mass * state.zdd;
  const Eigen::VectorXd bound = rest_bound(lin, state, mass, -mass * d_z);
  std::string left, rounding;
  for (int k = 0; k < lin.nf(); ++k) {
    left += (k ? ", " : "") + format_estimate(force[k]);
    rounding += (k ? ", " : "") + format_estimate(bound[k]);
  }
  throw AnalysisError(m.source + ": no equilibrium near value0 (" + z_text(lin, start.z) + ") at " +
                      format_time(p.t) + ": " + why + " after " + std::to_string(iterations) +
                      " Newton steps, at " + z_text(lin, p.z) +
                      ", the generalized forces B^T Q^A on the free coordinates are still " + left +
                      " (zero to rounding: " + rounding +
                      "; loads that balance in no position near it, or value0 far from one)");
}

[[noreturn]] void release_failed(const Linearizer& lin, const OperatingPoint& start,
                                 const OperatingPoint& p, int steps, const std::string& why) {
  throw AnalysisError(lin.model().mechanism().source + ": no equilibrium near value0 (" +
                      z_text(lin, start.z) + ") at " + format_time(p.t) +
                      ": the overdamped release from it " + why + " (after " +
                      std::to_string(steps) + " steps of the flow M_z dz/ds = B^T Q^A, at " +
                      z_text(lin, p.z) + "); --nearest gives Newton's nearest root instead");
}

// |B^T Q^A| <= rest_bound at the state evaluate() solved last, with its d_z.
bool at_rest(const Linearizer& lin, const MotionState& state, const Eigen::MatrixXd& d_z) {
  const Eigen::MatrixXd mass = lin.reduced_mass(state);
  return ((mass * state.zdd).array().abs() <= rest_bound(lin, state, mass, -mass * d_z).array())
      .all();
}

// Newton from p (evaluated: state, d_z) until |B^T Q^A| <= rest_bound.
int newton(Linearizer& lin, const OperatingPoint& start, OperatingPoint& p, MotionState& state,
           Eigen::MatrixXd& d_z, int max_iterations) {
  const int nf = lin.nf();
  const Eigen::VectorXd s = lin.scales();
  const auto scaled = [&](const Eigen::VectorXd& v) {
    return nf == 0 ? 0.0 : (v.array() / s.array()).abs().maxCoeff();
  };
  const auto merit = [&](const MotionState& st) {
    return (st.zdd.array() / s.array()).matrix().squaredNorm();
  };
  double trust = 1;
  int it = 0;
  for (; !at_rest(lin, state, d_z); ++it) {
    if (it == max_iterations)
      no_equilibrium(lin, start, p, state, d_z, it, "Newton did not converge");
    const Eigen::VectorXd newton = d_z.completeOrthogonalDecomposition().solve(-state.zdd);
    // The linear model must explain zdd: a singular K_z gives a least-squares step that leaves
    // the force it cannot balance.
    const double unexplained =
        newton.allFinite() ? scaled(d_z * newton + state.zdd) : scaled(state.zdd);
    const bool usable = newton.allFinite() && unexplained <= 0.5 * scaled(state.zdd);
    // A Newton step inside the trust region, else a step along zdd as long as the region.
    bool accepted = false;
    while (!accepted && trust > 1e-12) {
      const bool take_newton = usable && scaled(newton) <= trust;
      const Eigen::VectorXd step =
          take_newton ? newton : Eigen::VectorXd(state.zdd * (trust / scaled(state.zdd)));
      OperatingPoint trial = p;
      trial.z += step;
      MotionState ts;
      Eigen::MatrixXd tz;
      // A Newton step must lower |zdd|, or reach the rest within rounding; a fall is kept
      // while the forces still pull along it (the potential still falls: no equilibrium
      // passed) or |zdd| is lower.
      const bool solved = lin.evaluate(trial, ts, &tz);
      const bool falling =
          !take_newton && solved &&
          (ts.zdd.array() / s.array()).matrix().dot((state.zdd.array() / s.array()).matrix()) > 0;
      if (solved && (falling || merit(ts) < merit(state) || at_rest(lin, ts, tz))) {
        p = trial;
        state = ts;
        d_z = tz;
        accepted = true;
        if (take_newton) trust = std::min(1.0, std::max(trust, 2 * scaled(step)));
      } else {
        trust = std::min(trust, scaled(step)) / 4;
      }
    }
    if (!accepted) {
      // The Linearizer's last evaluation was of a trial: back to p for the message's forces.
      lin.evaluate(p, state, &d_z);
      no_equilibrium(lin, start, p, state, d_z, it,
                     "no step lowers the forces (they stay above their rounding)");
    }
  }
  return it;
}

bool has_negative(const ReducedStiffness& r) {
  return std::find(r.kinds.begin(), r.kinds.end(), Stability::kUnstable) != r.kinds.end();
}

// The overdamped release from p (evaluated: state, d_z, d_zd) until Newton may take over:
// K_z without a negative eigenvalue and a Newton step below 1e-3 scales that K_z explains, or
// the forces zero to rounding. Returns the flow's accepted steps.
int release(Linearizer& lin, const OperatingPoint& start, OperatingPoint& p, MotionState& state,
            Eigen::MatrixXd& d_z, Eigen::MatrixXd& d_zd) {
  const int nf = lin.nf();
  const Eigen::VectorXd s = lin.scales();
  const auto scaled = [&](const Eigen::VectorXd& v) {
    return nf == 0 ? 0.0 : (v.array() / s.array()).abs().maxCoeff();
  };
  const Eigen::MatrixXd identity = Eigen::MatrixXd::Identity(nf, nf);
  // One linearly implicit Euler step of dz/ds = zdd: (I - h J) dz = h zdd.
  const auto euler = [&](const Eigen::VectorXd& f, const Eigen::MatrixXd& j, double h) {
    return Eigen::VectorXd((identity - h * j).partialPivLu().solve(h * f));
  };
  // The step's local error against this tolerance (scales): 1e-6 absolute, 1e-3 of the step.
  constexpr double kAbsolute = 1e-6, kRelative = 1e-3;
  double h = 0;
  int steps = 0;
  for (;;) {
    if (at_rest(lin, state, d_z)) return steps;
    const ReducedStiffness r = reduced_stiffness(lin, state, d_z, d_zd);
    if (!has_negative(r)) {
      const Eigen::VectorXd newton = d_z.completeOrthogonalDecomposition().solve(-state.zdd);
      if (newton.allFinite() && scaled(newton) <= 1e-3 &&
          scaled(d_z * newton + state.zdd) <= 1e-3 * scaled(state.zdd))
        return steps;
    }
    if (steps == kFlowSteps)
      release_failed(lin, start, p, steps,
                     "has not settled (the limit is " + std::to_string(kFlowSteps) + " steps)");
    if (scaled(p.z - start.z) > kFlowTravel)
      release_failed(lin, start, p, steps,
                     "has not settled within " + format_number(kFlowTravel) +
                         " rad or length scales of the start");
    // The flow's unstable directions (J's eigenvalues with a positive real part) limit h to
    // 1/4 of their time constant: beyond it the implicit step would turn back towards the
    // unstable equilibrium it leaves.
    const Eigen::VectorXcd lambda = d_z.eigenvalues();
    double growth = 0, fastest = 0;
    for (Eigen::Index k = 0; k < lambda.size(); ++k) {
      growth = std::max(growth, lambda[k].real());
      fastest = std::max(fastest, std::abs(lambda[k]));
    }
    if (h == 0) {
      // First step: a move of 1e-3 scales, or 1e-3 of the fastest time constant.
      h = 1e-3 / std::max(scaled(state.zdd), 1e-300);
      if (fastest > 0) h = std::min(h, 1e-3 / fastest);
    }
    if (growth > 0) h = std::min(h, 0.25 / growth);
    bool accepted = false;
    for (int tries = 0; !accepted; ++tries) {
      const Eigen::VectorXd full = euler(state.zdd, d_z, h);
      const Eigen::VectorXd half = euler(state.zdd, d_z, h / 2);
      OperatingPoint mid = p, end = p;
      mid.z += half;
      MotionState ms, es;
      Eigen::MatrixXd mz, mzd, ez, ezd;
      bool solved = full.allFinite() && half.allFinite() && lin.evaluate(mid, ms, &mz, &mzd);
      double error = 0;
      if (solved) {
        const Eigen::VectorXd second = euler(ms.zdd, mz, h / 2);
        end.z = mid.z + second;
        error = scaled(half + second - full) / (kAbsolute + kRelative * scaled(half + second));
        solved = error <= 1 && lin.evaluate(end, es, &ez, &ezd);
      }
      if (solved) {
        p = end;
        state = es;
        d_z = ez;
        d_zd = ezd;
        accepted = true;
        h *= std::min(4.0, std::max(0.2, 0.9 / std::sqrt(std::max(error, 1e-16))));
      } else {
        h /= 4;
        if (tries == 60)
          release_failed(lin, start, p, steps,
                         error > 1 ? "cannot be followed (its steps collapse)"
                                   : "leaves where the mechanism assembles: " + lin.reason());
      }
    }
    ++steps;
  }
}

}  // namespace

Equilibrium find_equilibrium(Linearizer& lin, OperatingPoint p, EquilibriumSearch search,
                             int max_iterations) {
  p.zd.setZero(lin.nf());
  const OperatingPoint start = p;
  Equilibrium e;
  Eigen::MatrixXd d_z, d_zd;
  if (!lin.evaluate(p, e.state, &d_z, &d_zd))
    throw AnalysisError(lin.model().mechanism().source + ": no equilibrium search from value0 at " +
                        format_time(p.t) + ": " + lin.reason());
  if (search == EquilibriumSearch::kRest) {
    if (at_rest(lin, e.state, d_z)) {
      const ReducedStiffness r = reduced_stiffness(lin, e.state, d_z, d_zd);
      if (has_negative(r)) {
        // Eigenvalues ascend: the first is the most negative; its direction's largest
        // component is +1.
        p.z += 1e-6 * (r.directions.col(0).array() * lin.scales().array()).matrix();
        if (!lin.evaluate(p, e.state, &d_z, &d_zd))
          release_failed(lin, start, p, 0, "cannot leave the unstable start: " + lin.reason());
        e.left_start = true;
      }
    }
    e.flow_steps = release(lin, start, p, e.state, d_z, d_zd);
  }
  e.iterations = newton(lin, start, p, e.state, d_z, max_iterations);
  // The state and Jacobians at the equilibrium (the Linearizer's last evaluation may be of a
  // trial).
  if (!lin.evaluate(p, e.state, &d_z, &d_zd))
    throw AnalysisError(lin.model().mechanism().source + ": at the equilibrium: " + lin.reason());
  e.at = p;
  e.stiffness = reduced_stiffness(lin, e.state, d_z, d_zd);
  e.force = e.stiffness.mass * e.state.zdd;
  e.bound = rest_bound(lin, e.state, e.stiffness.mass, e.stiffness.stiffness);
  return e;
}

}  // namespace kinegen::codegen
