// kinegen runtime: what each coordinate measures and how large it is (the scales every
// tolerance is measured in), the predictor that starts Newton from the last step, and the test
// that a solved step followed the motion. Written once for the dense, sparse and block paths,
// the command line's analysis and the benchmarks. Standard library only.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <type_traits>
#include <utility>

namespace kinegen {

// What a coordinate measures. Generated headers list them as ints in this order
// (Model::coordinate_kinds).
enum class CoordinateKind : int { kLength = 0, kAngle = 1, kScalar = 2 };

namespace detail {

// Headers and systems from before the kinds table have body coordinates only, [x, y, phi].
constexpr CoordinateKind body_coordinate_kind(int k) {
  return k % 3 == 2 ? CoordinateKind::kAngle : CoordinateKind::kLength;
}

template <class System, class = void>
struct HasCoordinateScale : std::false_type {};
template <class System>
struct HasCoordinateScale<System,
                          std::void_t<decltype(std::declval<const System&>().coordinate_scale(0))>>
    : std::true_type {};

// The size against which coordinate k's Newton steps and errors are measured: its own scale
// when the system has one, else the length scale for x and y and 1 for angles.
template <class System>
double coordinate_scale(const System& sys, int k) {
  if constexpr (HasCoordinateScale<System>::value) {
    return sys.coordinate_scale(k);
  } else {
    return body_coordinate_kind(k) == CoordinateKind::kAngle ? 1.0 : sys.length_scale();
  }
}

template <class Model, class = void>
struct HasCoordinateTable : std::false_type {};
template <class Model>
struct HasCoordinateTable<
    Model, std::void_t<decltype(Model::coordinate_kinds), decltype(Model::coordinate_scales)>>
    : std::true_type {};

// The same for a generated header: its coordinate_scales table, or the fallback above for
// headers generated before it; and the inverses, computed once at compile time.
template <class Model>
constexpr double model_coordinate_scale(int k) {
  if constexpr (HasCoordinateTable<Model>::value) {
    return Model::coordinate_scales[k];
  } else {
    return body_coordinate_kind(k) == CoordinateKind::kAngle ? 1.0 : Model::length_scale;
  }
}
template <class Model>
struct InverseCoordinateScales {
  static constexpr auto kValues = [] {
    std::array<double, Model::nq> a{};
    for (int k = 0; k < Model::nq; ++k) a[k] = 1.0 / model_coordinate_scale<Model>(k);
    return a;
  }();
};
template <class Model>
constexpr CoordinateKind model_coordinate_kind(int k) {
  if constexpr (HasCoordinateTable<Model>::value) {
    return static_cast<CoordinateKind>(Model::coordinate_kinds[k]);
  } else {
    return body_coordinate_kind(k);
  }
}

}  // namespace detail

// Third-order Taylor predictor of the next position over h = t - t_previous, with the jerk
// estimated from the last two accelerations, (qdd - qdd_previous) / h_previous. The error is
// then O(h^4), below the tolerance at small steps, so one Newton iteration converges. Without
// two accelerations (first steps, after a reset) pass has_jerk = false: second order.
template <class Scalar>
class TaylorPredictor {
 public:
  TaylorPredictor(Scalar h, Scalar h_previous, bool has_jerk)
      : h_(h),
        h2_(h * h / Scalar(2)),
        h3_(has_jerk && h_previous != Scalar(0) ? h * h * h / (Scalar(6) * h_previous) : Scalar(0)),
        has_jerk_(h3_ != Scalar(0)) {}
  // The predicted value of one coordinate; qdd_previous is read only with a jerk, so it may be
  // anything (NaN included) otherwise.
  Scalar operator()(Scalar q, Scalar qd, Scalar qdd, Scalar qdd_previous) const {
    const Scalar p = q + h_ * qd + h2_ * qdd;
    return has_jerk_ ? p + h3_ * (qdd - qdd_previous) : p;
  }

 private:
  Scalar h_, h2_, h3_;
  bool has_jerk_;
};

// The outcome of the jump test below, in scaled units (lengths over their coordinate's scale,
// angles in radians): how far the position moved, how far it is from the nearest velocity-based
// estimate, and the mismatch allowed.
struct MotionCheck {
  double change = 0, miss = 0, allowed = 0;
  bool jumped() const { return !(miss <= allowed); }
};

// Whether a solved step from (q0, qd0, qdd0) to (q1, qd1, qdd1) over h followed the motion.
// On a smooth motion q1 - q0 = h (qd0 + qd1) / 2 + h^2 (qdd0 - qdd1) / 12 + O(h^5)
// (Euler-Maclaurin). A motion law's warned boundary makes qd or qdd jump at a grid time,
// where the one-sided Taylor estimate from the other end still holds
// (q0 + h qd0 + h^2 qdd0 / 2, or q1 - h qd1 + h^2 qdd1 / 2): the nearest of the three counts.
// A solution that misses all three by more than `fraction` of the motion the velocities give
// over the step, h max |qd| (plus a rounding floor in the scalar's epsilon), was not reached
// along the motion: Newton jumped to another assembly branch, or the step is too coarse to
// tell. The allowance is not scaled by the change itself: a whole turn that Newton added to an
// angle, over a step whose acceleration terms happen to explain much of it, would then allow
// itself (an indexer's crank in one step from rest to rest); such a step is refused, and taken
// in sub-steps (substeps, below). coords: the coordinates to
// compare (all, or those Newton iterates where every other one follows from them and t); V:
// anything indexable with [k]; inv_scale(k): 1 / the coordinate's scale (multiplications: this
// runs every step).
template <class Coords, class V, class InvScaleOf>
MotionCheck check_motion(const Coords& coords, double h, const V& q0, const V& qd0, const V& qdd0,
                         const V& q1, const V& qd1, const V& qdd1, InvScaleOf&& inv_scale,
                         double fraction, double eps) {
  MotionCheck c;
  const double half_h = 0.5 * h, h2_12 = h * h / 12;
  double motion = 0, size = 0;
  for (const int k : coords) {
    const double w = inv_scale(k);
    const double dq = static_cast<double>(q1[k]) - static_cast<double>(q0[k]);
    const double v0 = static_cast<double>(qd0[k]), v1 = static_cast<double>(qd1[k]);
    const double trapezoid = dq - half_h * (v0 + v1) -
                             h2_12 * (static_cast<double>(qdd0[k]) - static_cast<double>(qdd1[k]));
    c.miss = std::max(c.miss, std::abs(trapezoid) * w);
    c.change = std::max(c.change, std::abs(dq) * w);
    motion = std::max(motion, std::max(std::abs(v0), std::abs(v1)) * w);
    size = std::max(size, std::abs(static_cast<double>(q1[k])) * w);
  }
  motion *= std::abs(h);
  c.allowed = fraction * motion + 1e-6 + 1e4 * eps + 64 * eps * size;
  if (c.miss <= c.allowed) return c;  // the smooth case: one pass
  double miss_old = 0, miss_new = 0;
  const double h2_2 = 0.5 * h * h;
  for (const int k : coords) {
    const double w = inv_scale(k);
    const double dq = static_cast<double>(q1[k]) - static_cast<double>(q0[k]);
    miss_old = std::max(
        miss_old,
        std::abs(dq - h * static_cast<double>(qd0[k]) - h2_2 * static_cast<double>(qdd0[k])) * w);
    miss_new = std::max(
        miss_new,
        std::abs(dq - h * static_cast<double>(qd1[k]) + h2_2 * static_cast<double>(qdd1[k])) * w);
  }
  c.miss = std::min({c.miss, miss_old, miss_new});
  return c;
}

// Sub-steps: the most halvings SolverOptions::substep_halvings may ask for (the pending times
// are a fixed array), and the number `kinegen analyze` uses (a step refused at 1/4096 of its
// length is refused for a reason, not for its size).
constexpr int kMaxSubstepHalvings = 40;
constexpr int kAnalyzeSubstepHalvings = 12;

// A step from t_from (the last accepted time) to t that is refused (its solve failed, or it
// jumped: check_motion) is retried as two halves, each halved again while refused, as long as
// the refused step is longer than (t - t_from) / 2^halvings; every sub-step is a full step with
// all its checks, and only the last one lands on t. attempt(to) tries one step from the last
// accepted state to `to` and, when it succeeds, makes that the last accepted state; restore()
// puts the caller's q, qd and qdd back to the last accepted state after a refusal. Returns true
// when t was reached; otherwise failed_at is the end of the refused step at the finest length
// (halvings = 0: t itself, a plain step). Written once for `kinegen analyze` and Solver::step,
// which so take the same sub-steps bit for bit. No allocation.
template <class Scalar, class Attempt, class Restore>
bool substeps(Scalar t_from, Scalar t, int halvings, Attempt&& attempt, Restore&& restore,
              Scalar& failed_at) {
  halvings = std::clamp(halvings, 0, kMaxSubstepHalvings);
  Scalar shortest = t - t_from;  // |a refused step| at most this fails: (t - t_from) / 2^halvings
  for (int k = 0; k < halvings; ++k) shortest /= Scalar(2);
  Scalar pending[kMaxSubstepHalvings + 1];  // the times still to reach, the nearest last
  int n = 0;
  pending[n++] = t;
  Scalar from = t_from;
  while (n > 0) {
    const Scalar to = pending[n - 1];
    if (attempt(to)) {
      from = to;
      --n;
      continue;
    }
    restore();
    const Scalar mid = from + (to - from) / Scalar(2);
    using std::abs;
    if (!(abs(to - from) > abs(shortest)) || !(mid != from && mid != to) ||
        n > kMaxSubstepHalvings) {
      failed_at = to;
      return false;
    }
    pending[n++] = mid;
  }
  return true;
}

}  // namespace kinegen
