// The reference integrator: Gragg-Bulirsch-Stoer extrapolation in CLN arithmetic on
// ReferenceDynamics (see analysis/reference_dynamics.hpp). The step, order and rejection rules
// are those of Hairer, Norsett and Wanner, Solving ODEs I, section II.9 (their code ODEX),
// without dense output: steps land exactly on the grid's times, on every breakpoint (a driver's
// or a load's kink in t, analysis/breakpoints.hpp; a state-dependent one located like a
// stop_when root) and on a stop_when root. No step spans a breakpoint: the extrapolation
// assumes a smooth right-hand side over its step.
#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>

#include "kinegen/codegen/analysis/breakpoints.hpp"
#include "kinegen/codegen/analysis/kinematics.hpp"
#include "kinegen/codegen/analysis/reference_dynamics.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/base/interrupt.hpp"
#include "kinegen/codegen/program/program.hpp"

namespace kinegen::codegen {

using GiNaC::ex;
using GiNaC::numeric;
using Vector = std::vector<numeric>;

namespace {

// ODEX's constants: the step factor's bounds, safety factors, order change thresholds.
constexpr double kFacMin = 0.02, kFacMax = 4.0, kSafe1 = 0.65, kSafe2 = 0.94;
constexpr double kOrderDown = 0.8, kOrderUp = 0.9;
// Consecutive failed evaluations (Newton, a branch, ...) that end the run.
constexpr int kMaxFailures = 40;
// stop_when's error bound E, relative to its scale: below what a double run resolves, so the
// reference finds every crossing a double run can.
constexpr double kStopErrorBound = 1e-15;

// |x| as a double, at most 1e300 (a scaled error of a wild first try may exceed double's
// range when D is large).
double bounded(const numeric& x) {
  const numeric a = GiNaC::abs(x);
  return a > numeric(10).power(300) ? 1e300 : a.to_double();
}

// The tableau's lines for D digits: ODEX's optimal order grows like 0.6 D, capped where a
// step's work (about columns^2 evaluations) stops paying.
int extrapolation_columns(int digits) { return std::clamp(digits / 3 + 4, 9, 60); }

// Extrapolating with `columns` lines of the harmonic sequence multiplies the rounding of the
// midpoint values by up to the sum of |weights| of the extrapolation to h = 0 (its Lebesgue
// constant, about 5^columns: 1e4 for 14 lines), so the arithmetic carries that many more
// digits (and two more) than the tolerance asks.
int guard_digits(int columns) {
  double sum = 0;
  for (int j = 1; j <= columns; ++j) {
    double w = 1;
    for (int i = 1; i <= columns; ++i)
      if (i != j) w *= double(j) * j / (double(j) * j - double(i) * i);
    sum += std::abs(w);
  }
  return static_cast<int>(std::ceil(std::log10(sum))) + 2;
}

// An accepted point: the state y = [z, zd, work], its derivative and the full state there.
struct StepPoint {
  numeric t;
  Vector y, f;
  ReferenceMotionState state;
};

class Extrapolation {
 public:
  // digits: the requested D (the tolerance's); columns: extrapolation_columns(D).
  Extrapolation(ReferenceDynamics& dynamics, const std::vector<double>& scales, int digits,
                int columns, const SimulateOptions& options)
      : dyn_(dynamics), scales_(scales), options_(options), kmax_(columns) {
    // The local tolerance: 10^-(D-2) leaves about D - 5 digits after a few hundred steps
    // (a damped four-bar over 2 s at 30 digits: 9e-27 from a 45-digit run, 2e-24 with
    // 10^-(D-4)).
    tolerance_ = numeric(10).power(-(digits - 2));  // below double's range for large D
    for (int j = 1; j <= kmax_ + 1; ++j) work_.push_back(j == 1 ? n(1) : work_.back() + n(j) - 1);
    k_ = std::clamp(static_cast<int>((digits - 2) * 0.6 + 1.5), 3, kmax_ - 1);
  }

  // y' at (t, y) and the state there; throws AnalysisError.
  void derivative(const numeric& t, const Vector& y, Vector& f, ReferenceMotionState& s) {
    const int nf = dyn_.nf();
    ++stats.evaluations;
    // An evaluation takes milliseconds at the digits allowed: a stop asked for is seen at once.
    interruption_point();
    dyn_.evaluate(t, Vector(y.begin(), y.begin() + nf), Vector(y.begin() + nf, y.begin() + 2 * nf),
                  s);
    f.resize(y.size());
    for (int k = 0; k < nf; ++k) {
      f[k] = y[nf + k];
      f[nf + k] = s.zdd[k];
    }
    f[2 * nf] = s.power;
  }
  StepPoint point(const numeric& t, const Vector& y) {
    StepPoint p{t, y, {}, {}};
    derivative(t, y, p.f, p.state);
    return p;
  }
  // A first step: one whose change h |y'| is a hundredth of |y| + its scale.
  void initial_step(const StepPoint& p, double span) {
    double rate = 0;
    for (std::size_t i = 0; i < p.y.size(); ++i)
      rate = std::max(rate,
                      bounded(GiNaC::abs(p.f[i]) / (exact_numeric(scale(i)) + GiNaC::abs(p.y[i]))));
    h_ = rate > 0 ? std::min(0.01 / rate, span) : 1e-3 * span;
  }

  // One accepted step from p towards t_end (shorter where the controller asks); p becomes
  // the new point. Throws AnalysisError after kMaxFailures failed evaluations in a row.
  void step(StepPoint& p, const numeric& t_end) {
    for (int failures = 0;;) {
      if (options_.interrupted && options_.interrupted()) throw AnalysisError("interrupted");
      const double remaining = (t_end - p.t).to_double();
      const bool last = h_ >= remaining * (1 - 1e-9);
      const double h = last ? remaining : h_;
      const numeric t_new = last ? t_end : dyn_.to_float(p.t + exact_numeric(h));
      Vector y;
      double h_next = h;
      std::string reason;
      try {
        const int order = k_;
        if (attempt(p, t_new, y, h_next)) {
          StepPoint next = point(t_new, y);
          ++stats.steps;
          // A step cut short (a grid time, a breakpoint, stop_when's limit) keeps its order
          // and the larger step size: the lower order that is cheaper on a short step fails
          // the next full step's error test, and each rejection lowers the order further,
          // down to steps of 1e-14 (the pendulum at 60 digits near a stop_when root).
          h_ = last ? std::max(h_next, h_) : h_next;
          if (last) k_ = std::max(k_, order);
          p = std::move(next);
          return;
        }
        ++stats.rejected;
        h_ = h_next;
        if (!(h_ > 1e-14 * std::max(1.0, std::abs(p.t.to_double()))))
          throw AnalysisError("the step size fell below 1e-14 of t (the error test fails)");
        continue;
      } catch (const AnalysisError& e) {
        reason = e.what();
      }
      // A failed evaluation: CVODE's policy, a smaller step.
      ++stats.rejected;
      reject_ = true;
      h_ = h / 4;
      if (++failures >= kMaxFailures || !(h_ > 1e-14 * std::max(1.0, std::abs(p.t.to_double()))))
        throw AnalysisError(reason);
    }
  }

  // The step size and order of `o` (a copy taken before a step that is taken again).
  void restore_controller(const Extrapolation& o) {
    h_ = o.h_;
    k_ = o.k_;
    reject_ = o.reject_;
  }

  ReferenceSimulationStats stats;

 private:
  static int n(int j) { return 2 * j; }  // the harmonic sequence, j from 1
  double scale(std::size_t i) const { return i < scales_.size() ? scales_[i] : energy_scale; }

 public:
  double energy_scale = 1;

 private:
  // T_j1: the modified midpoint rule with n(j) substeps from p to t_new.
  Vector midpoint(const StepPoint& p, const numeric& t_new, int j) {
    const int steps = n(j);
    const numeric h = (t_new - p.t) / steps;
    dyn_.start_from(p.state);
    Vector u0 = p.y, u1(p.y.size()), f;
    for (std::size_t i = 0; i < u1.size(); ++i) u1[i] = u0[i] + h * p.f[i];
    ReferenceMotionState s;
    for (int m = 1; m < steps; ++m) {
      derivative(p.t + h * m, u1, f, s);
      for (std::size_t i = 0; i < u1.size(); ++i) {
        const numeric u2 = u0[i] + 2 * h * f[i];
        u0[i] = u1[i];
        u1[i] = u2;
      }
    }
    return u1;
  }

  // The scaled RMS norm of T_jj - T_j,j-1.
  double error(const StepPoint& p, const Vector& best, const Vector& next) const {
    double sum = 0;
    for (std::size_t i = 0; i < best.size(); ++i) {
      const numeric size = std::max(GiNaC::abs(p.y[i]), GiNaC::abs(best[i]));
      const numeric sc = tolerance_ * (exact_numeric(scale(i)) + size);
      const double e = bounded((best[i] - next[i]) / sc);
      sum += e * e;
    }
    return std::sqrt(sum / best.size());
  }

  // One attempt with HNW's convergence monitor in lines k-1, k and k+1; true when accepted,
  // with y and the next step and order.
  bool attempt(const StepPoint& p, const numeric& t_new, Vector& y, double& h_next) {
    const double h = (t_new - p.t).to_double();
    std::vector<double> hh(kmax_ + 2, h), w(kmax_ + 2, 0);
    std::vector<Vector> row;  // the tableau's last row, T_j1 .. T_jj
    int kc = 0;
    bool accepted = false;
    for (int j = 1; j <= k_ + 1 && kc == 0; ++j) {
      std::vector<Vector> next{midpoint(p, t_new, j)};
      for (int l = 1; l < j; ++l) {
        const numeric ratio = numeric(n(j) * n(j) - n(j - l) * n(j - l), n(j - l) * n(j - l));
        Vector v(next[l - 1].size());
        for (std::size_t i = 0; i < v.size(); ++i)
          v[i] = next[l - 1][i] + (next[l - 1][i] - row[l - 1][i]) / ratio;
        next.push_back(std::move(v));
      }
      row = std::move(next);
      stats.largest_column = std::max(stats.largest_column, j);
      if (j < 2) continue;
      const double err = std::max(error(p, row[j - 1], row[j - 2]), 1e-300);
      const double expo = 1.0 / (2 * j - 1), facmin = std::pow(kFacMin, expo);
      const double fac =
          std::clamp(std::pow(err / kSafe1, expo) / kSafe2, facmin, kFacMax / facmin);
      hh[j] = h / fac;
      w[j] = work_[j - 1] / hh[j];
      if (j < k_ - 1) continue;
      const double n1 = n(1);
      if (err <= 1) {
        kc = j, accepted = true;
      } else if ((j == k_ - 1 && err > std::pow(n(k_ + 1) * n(k_) / (n1 * n1), 2)) ||
                 (j == k_ && err > std::pow(n(k_ + 1) / n1, 2)) || j == k_ + 1) {
        kc = j;
      }
    }
    if (!accepted) {
      int k = std::min({k_, kc, kmax_ - 1});
      if (k > 2 && w[k - 1] < kOrderDown * w[k]) --k;
      k_ = std::max(k, 2);
      h_next = hh[k_] > 0 ? hh[k_] : h / 2;
      reject_ = true;
      return false;
    }
    y = row[kc - 1];
    int kopt = kc;
    if (kc == 2) {
      kopt = std::min(3, kmax_ - 1);
    } else if (kc <= k_) {
      if (w[kc - 1] < kOrderDown * w[kc]) kopt = kc - 1;
      if (w[kc] < kOrderUp * w[kc - 1]) kopt = std::min(kc + 1, kmax_ - 1);
    } else {
      kopt = kc - 1;
      if (kc > 3 && w[kc - 2] < kOrderDown * w[kc - 1]) kopt = kc - 2;
      if (w[kc] < kOrderUp * w[kopt]) kopt = std::min(kc, kmax_ - 1);
    }
    if (reject_) kopt = std::min(kopt, kc);
    h_next = kopt <= kc ? hh[kopt] : hh[kc] * work_[kopt - 1] / work_[kc - 1];
    if (reject_) h_next = std::min(h_next, h);
    reject_ = false;
    k_ = std::max(kopt, 2);
    return true;
  }

  ReferenceDynamics& dyn_;
  std::vector<double> scales_;
  const SimulateOptions& options_;
  numeric tolerance_;
  double h_ = 0;
  int kmax_ = 9, k_ = 3;
  bool reject_ = false;
  std::vector<double> work_;  // A_j: evaluations of lines 1..j, the end point's included
};

}  // namespace

namespace {

// stop_when's failure to evaluate, named by the file, the item and its line: not one of the
// integrator's failures (no smaller step helps), so the run ends with this message as it is.
class StopWhenError : public AnalysisError {
 public:
  using AnalysisError::AnalysisError;
};

// Whether e holds a derivative the expression language cannot write (a function without one).
bool has_unknown_derivative(const ex& e) {
  if (GiNaC::is_a<GiNaC::fderivative>(e)) return true;
  for (std::size_t k = 0; k < e.nops(); ++k)
    if (has_unknown_derivative(e.op(k))) return true;
  return false;
}

// stop_when at a state in high precision: its tape, or, where it reads force columns,
// the expression evaluated with them (ReferenceForces) substituted. Without force
// columns its exact rate too: g' = dg/dt + dg/dq qd (at qdd = 0, one output) + dg/dqd qdd.
// Its error bound at t0 is the double run's (stop_when_bound): both judge t0 alike.
class StopFunction {
 public:
  StopFunction(const CompiledModel& model, const ForceModel& forces, ReferenceDynamics& dyn)
      : model_(model), dyn_(dyn) {
    const SymbolicModel& sym = model.symbolic();
    const SymbolTable& s = model.symbols();
    if (sym.stop_when.is_zero() && !model.mechanism().stop_when) return;
    active_ = true;
    if (sym.stop_force_columns.empty()) {
      std::vector<ex> outputs{sym.stop_when};
      try {
        ex rate0 = sym.stop_when.diff(s.t());
        std::vector<ex> by_qd;
        for (int k = 0; k < s.nq(); ++k) {
          rate0 += sym.stop_when.diff(s.q(k)) * s.qd(k);
          by_qd.push_back(sym.stop_when.diff(s.qd(k)));
        }
        std::vector<ex> by_q;
        for (int k = 0; k < s.nq(); ++k) by_q.push_back(sym.stop_when.diff(s.q(k)));
        bool known = !has_unknown_derivative(rate0);
        for (const ex& d : by_qd) known = known && !has_unknown_derivative(d);
        for (const ex& d : by_q) known = known && !has_unknown_derivative(d);
        if (known) {
          outputs.push_back(rate0);
          outputs.insert(outputs.end(), by_qd.begin(), by_qd.end());
          outputs.insert(outputs.end(), by_q.begin(), by_q.end());
          has_rate_ = true;
        }
      } catch (const std::exception&) {
        has_rate_ = false;  // no rate: the steps are not limited by it
      }
      handle_ = dyn.evaluator().add_outputs(outputs);
      return;
    }
    forces_ = std::make_unique<ReferenceForces>(model, forces, dyn.digits());
    expression_ = substitute_params(sym.stop_when, s, sym.param_values);
    for (GiNaC::const_preorder_iterator it = expression_.preorder_begin();
         it != expression_.preorder_end(); ++it)
      if (GiNaC::is_a<GiNaC::symbol>(*it)) {
        const Input in = s.classify(*it);
        if (in.kind == InputKind::kParam && in.index >= s.num_params())
          extras_.emplace_back(*it, in.index - s.num_params());
      }
  }
  bool active() const { return active_; }
  bool has_rate() const { return has_rate_; }

  // The rule at t0 (StopWhenLevel) with E as the double run computes it (stop_when_bound):
  // rtol |g| plus, where the rate is known, each coordinate's and rate's atol share, so that
  // every method judges t0 alike.
  StopWhenLevel level_at_t0(const ReferenceMotionState& st, const SimulateOptions& options) {
    const numeric g = value_and_rate(st, nullptr);
    const std::size_t nq = st.q.size();
    std::vector<double> by_q, by_qd;
    try {
      if (handle_ >= 0 && has_rate_) {
        const Vector v = dyn_.evaluator().evaluate(handle_, st.q, st.qd, st.t);
        for (std::size_t k = 0; k < nq; ++k) {
          by_qd.push_back(v[2 + k].to_double());
          by_q.push_back(v[2 + nq + k].to_double());
        }
      }
    } catch (const std::exception&) {
      by_q.clear();  // a derivative that does not evaluate adds no share, as in a double run
      by_qd.clear();
    }
    // The shares where the double run has them (its program's rate), so that both agree.
    const bool known =
        model_.stop_programs().has_rate && by_q.size() == nq && by_qd.size() == nq;
    const double bound = stop_when_bound(std::abs(g.to_double()), known ? by_q.data() : nullptr,
                                         known ? by_qd.data() : nullptr,
                                         model_.symbolic().coordinate_scales, options);
    return StopWhenLevel(g.to_double(), bound);
  }

  numeric operator()(const ReferenceMotionState& st) { return value_and_rate(st, nullptr); }
  numeric rate(const ReferenceMotionState& st) {
    numeric r;
    value_and_rate(st, &r);
    return r;
  }

  // g at st and, when rate is given and has_rate(), g' there. Throws StopWhenError when g is
  // not a finite real number.
  numeric value_and_rate(const ReferenceMotionState& st, numeric* rate) {
    try {
      if (handle_ >= 0) {
        const Vector v = dyn_.evaluator().evaluate(handle_, st.q, st.qd, st.t);
        if (rate && has_rate_) {
          numeric r = v[1];
          for (std::size_t k = 0; k < st.qdd.size(); ++k) r = r + v[2 + k] * st.qdd[k];
          *rate = r;
        }
        return v[0];
      }
      return with_force_columns(st);
    } catch (const StopWhenError&) {
      throw;
    } catch (const std::exception& e) {
      fail(st.t, e.what());
    }
  }

 private:
  numeric with_force_columns(const ReferenceMotionState& st) {
    const DigitsGuard guard(dyn_.digits());
    ReferenceRow row;
    row.t = st.t;
    row.q = st.q;
    row.qd = st.qd;
    row.qdd = st.qdd;
    const std::vector<numeric> columns = forces_->solve(row);
    const SymbolTable& s = model_.symbols();
    GiNaC::exmap map;
    for (int k = 0; k < s.nq(); ++k) {
      map[s.q(k)] = st.q[k];
      map[s.qd(k)] = st.qd[k];
    }
    map[s.t()] = st.t;
    for (const auto& [symbol, k] : extras_)
      map[symbol] = columns[model_.symbolic().stop_force_columns[k]];
    const ex v = GiNaC::evalf(expression_.subs(map));
    if (!GiNaC::is_a<numeric>(v) || !GiNaC::ex_to<numeric>(v).is_real())
      fail(st.t, "not a real number");
    return dyn_.to_float(GiNaC::ex_to<numeric>(v));
  }

  [[noreturn]] void fail(const numeric& t, const std::string& why) const {
    const Mechanism& m = model_.mechanism();
    const int line = m.stop_when ? m.stop_when->loc.line : 0;
    throw StopWhenError(m.source + ":" + std::to_string(line) +
                        ": stop_when: not a finite real number at " + format_time(t.to_double()) +
                        " (" + why + ")");
  }

  const CompiledModel& model_;
  ReferenceDynamics& dyn_;
  bool active_ = false, has_rate_ = false;
  int handle_ = -1;
  std::unique_ptr<ReferenceForces> forces_;
  ex expression_;
  std::vector<std::pair<ex, int>> extras_;
};

// The columns of a row: points, outputs, energy, forces.
class RowBuilder {
 public:
  RowBuilder(const CompiledModel& model, const ForceModel& forces, ReferenceDynamics& dyn,
             bool with_forces)
      : model_(model), dyn_(dyn) {
    const SymbolicModel& sym = model.symbolic();
    const DigitsGuard guard(dyn.digits());
    for (const auto& [x, y] : sym.point_s) {
      const auto value = [&](const ex& e) {
        return dyn.to_float(GiNaC::ex_to<numeric>(
            GiNaC::evalf(substitute_params(e, model.symbols(), sym.param_values))));
      };
      offsets_.push_back({value(x), value(y)});
    }
    outputs_ = static_cast<int>(sym.output_values.size());
    if (outputs_ > 0) {
      std::vector<ex> all = sym.output_values;
      for (const ex& e : output_rate_expressions(sym)) all.push_back(e);
      handle_ = dyn.evaluator().add_outputs(all);
    }
    if (with_forces) forces_ = std::make_unique<ReferenceForces>(model, forces, dyn.digits());
  }

  ReferenceSimulatedRow row(const StepPoint& p) {
    const DigitsGuard guard(dyn_.digits());
    const ReferenceMotionState& s = p.state;
    const int nq = model_.nq(), nf = dyn_.nf();
    ReferenceSimulatedRow r;
    r.row.t = p.t;
    r.row.q = s.q;
    r.row.qd = s.qd;
    r.row.qdd = s.qdd;
    const auto& points = model_.mechanism().points;
    for (std::size_t k = 0; k < points.size(); ++k) {
      const int b = 3 * points[k].body;
      const numeric c = GiNaC::cos(s.q[b + 2]), sn = GiNaC::sin(s.q[b + 2]);
      r.row.points.push_back(
          point_kinematics(&s.q[b], &s.qd[b], &s.qdd[b], c, sn, offsets_[k][0], offsets_[k][1]));
    }
    if (handle_ >= 0) {
      const Vector v = dyn_.evaluator().evaluate(handle_, s.q, s.qd, p.t);
      const auto& reads_velocity = model_.symbolic().output_reads_velocity;
      assemble_outputs(reads_velocity, nq, v.data(), v.data() + outputs_, s.qdd.data(), numeric(0),
                       r.row.outputs);
      r.row.velocity_outputs = reads_velocity;
    }
    r.z = s.z;
    r.zd = s.zd;
    r.zdd = s.zdd;
    const auto e = dyn_.energy(s);
    r.kinetic = e[0];
    r.potential = e[1];
    r.work = p.y[2 * nf];
    if (!have_energy0_) energy0_ = e[0] + e[1], have_energy0_ = true;
    r.balance = e[0] + e[1] - r.work - energy0_;
    if (forces_) r.forces = forces_->solve(r.row);
    return r;
  }

 private:
  const CompiledModel& model_;
  ReferenceDynamics& dyn_;
  std::vector<std::array<numeric, 2>> offsets_;
  int outputs_ = 0, handle_ = -1;
  std::unique_ptr<ReferenceForces> forces_;
  bool have_energy0_ = false;
  numeric energy0_;
};

// The root of a function of the state between two accepted points a and b (f(a) and f(b) of
// opposite signs, f(a) != 0), by the Illinois method on the time, each trial point integrated
// from a with the same controller: the first point at or past the root, within `tolerance`.
template <class F>
StepPoint locate_root(const Extrapolation& gbs, F&& f, const StepPoint& a, numeric fa, StepPoint b,
                      numeric fb, const numeric& tolerance) {
  StepPoint lo = a;
  const bool a_negative = fa.is_negative();
  int side = 0;
  for (int it = 0; it < 200 && b.t - lo.t > tolerance; ++it) {
    numeric t = (lo.t * fb - b.t * fa) / (fb - fa);
    if (!(t > lo.t && t < b.t)) t = (lo.t + b.t) / 2;
    StepPoint m = a;
    Extrapolation sub = gbs;
    while (m.t < t) sub.step(m, t);
    const numeric fm = f(m.state);
    if (!fm.is_zero() && fm.is_negative() == a_negative) {
      lo = std::move(m);
      fa = fm;
      if (side == -1) fb = fb / 2;
      side = -1;
    } else {
      b = std::move(m);
      fb = fm;
      if (side == 1) fa = fa / 2;
      side = 1;
    }
  }
  return b;
}

// stop_when's root between two accepted points (g(a) < level <= g(b)).
StepPoint find_root(const Extrapolation& gbs, StopFunction& stop, const numeric& level,
                    const StepPoint& a, const numeric& ga, const StepPoint& b, const numeric& gb,
                    const numeric& tolerance) {
  return locate_root(
      gbs, [&](const ReferenceMotionState& s) { return stop(s) - level; }, a, ga - level, b,
      gb - level, tolerance);
}

// The drivers' and loads' kinks that depend on the state (analysis/breakpoints.hpp): each
// switch's argument at a state, and the first level one of them crosses between two points.
class StateBreakpoints {
 public:
  StateBreakpoints(const CompiledModel& model, const ForceModel& forces, ReferenceDynamics& dyn)
      : dyn_(dyn), switches_(state_switches(model, forces)) {
    if (switches_.empty()) return;
    std::vector<ex> arguments;
    for (const StateSwitch& s : switches_) arguments.push_back(s.argument);
    handle_ = dyn.evaluator().add_outputs(arguments);
  }
  bool active() const { return handle_ >= 0; }
  Vector values(const ReferenceMotionState& s) {
    return dyn_.evaluator().evaluate(handle_, s.q, s.qd, s.t);
  }

  // The step from a to b (switch values va, vb) ends at the first crossing of a level that
  // starts off it (a level that a or b lies on is no crossing to locate: the step already ends
  // or starts there), located to `tolerance`; b itself when none is crossed.
  StepPoint first_crossing(const Extrapolation& gbs, const StepPoint& a, const Vector& va,
                           const StepPoint& b, const Vector& vb, const numeric& tolerance) {
    std::optional<StepPoint> first;
    for (std::size_t k = 0; k < switches_.size(); ++k) {
      const double x = va[k].to_double(), y = vb[k].to_double();
      if (!std::isfinite(x) || !std::isfinite(y)) continue;
      const double margin = 1e-12 * std::max({std::abs(x), std::abs(y), 1.0});
      std::vector<double> levels;
      switches_[k].levels.within(std::min(x, y) - margin, std::max(x, y) + margin, levels);
      for (double level : levels) {
        const numeric l = exact_numeric(level);
        const numeric fa = va[k] - l, fb = vb[k] - l;
        if (fa.is_zero() || fb.is_zero() || fa.is_negative() == fb.is_negative()) continue;
        const StepPoint at = locate_root(
            gbs, [&](const ReferenceMotionState& s) { return values(s)[k] - l; }, a, fa, b, fb,
            tolerance);
        if (!first || at.t < first->t) first = at;
      }
    }
    return first ? *first : b;
  }

 private:
  ReferenceDynamics& dyn_;
  std::vector<StateSwitch> switches_;
  int handle_ = -1;
};

}  // namespace

ReferenceSimulationStats run_reference_simulation_exact(
    const CompiledModel& model, const ForceModel& forces, const TimeGrid& grid, int digits,
    const std::function<void(const ReferenceSimulatedRow&)>& sink, const SimulateOptions& options) {
  check_reference_digits(digits);
  check_input_coverage(model, grid.t0, grid.t1);
  check_reference_stop_when(model);
  const int columns = extrapolation_columns(digits);
  ReferenceDynamics dyn(model, forces, digits + guard_digits(columns), grid.t0);
  const DigitsGuard guard(dyn.digits());
  const std::string& file = model.mechanism().source;
  std::vector<double> scales = dyn.scales();
  scales.insert(scales.end(), dyn.scales().begin(), dyn.scales().end());
  Extrapolation gbs(dyn, scales, digits, columns, options);
  RowBuilder rows(model, forces, dyn, options.forces_columns != nullptr);
  StopFunction stop(model, forces, dyn);
  const ReferenceMotionState& s0 = dyn.initial();
  Vector y = s0.z;
  y.insert(y.end(), s0.zd.begin(), s0.zd.end());
  y.push_back(0);
  StepPoint p{s0.t, y, {}, {}};
  const auto fail = [&](const numeric& t, const std::string& why) {
    throw AnalysisError(file + ": reference simulation (" + std::to_string(digits) +
                        " digits) failed at " + format_time(t.to_double()) + ": " + why);
  };
  try {
    p = gbs.point(s0.t, y);
  } catch (const AnalysisError& e) {
    fail(p.t, e.what());
  }
  const auto e0 = dyn.energy(p.state);
  gbs.energy_scale = energy_scale((GiNaC::abs(e0[0]) + GiNaC::abs(e0[1])).to_double(), forces,
                                  model.symbolic().length_scale);
  gbs.initial_step(p, grid.t1 - grid.t0);
  const auto emit = [&](const StepPoint& at) {
    sink(rows.row(at));
    if (options.progress) options.progress(at.t.to_double());
    interruption_point();
  };
  emit(p);
  const numeric root_tolerance =
      numeric(10).power(-(digits - 5)) *
      dyn.to_float(exact_numeric(std::max(std::abs(grid.t1), grid.t1 - grid.t0)));
  // stop_when (docs/format.md, Simulation): g and g' at the last point; the rule at t0 and the
  // level to cross (StopWhenLevel).
  numeric g, g_rate;
  double g_scale = 1;
  StopWhenLevel level = stop.active() ? stop.level_at_t0(p.state, options) : StopWhenLevel(0, 0);
  if (stop.active()) {
    g = stop.value_and_rate(p.state, &g_rate);
    g_scale = std::max(g_scale, bounded(g));
    if (level.stops_at_t0()) {
      gbs.stats.stopped = true;
      gbs.stats.stop_time = p.t.to_double();
      return gbs.stats;
    }
  }
  // The largest step g allows from a point: |g'| h <= (|g| + E)/8, E = kStopErrorBound times
  // g's scale (the largest |g| so far, at least 1), so that no excursion of g beyond E fits
  // between two points unseen.
  const auto stop_limit = [&](const numeric& value, const numeric& rate) {
    const double r = bounded(rate);
    return r > 0 ? (bounded(value) + kStopErrorBound * g_scale) / (8 * r) : 1e300;
  };
  // The breakpoints in t, in the arithmetic's precision; those of the state, located on the way.
  std::vector<numeric> fixed;
  for (double b : breakpoints(model, forces, grid.t0, grid.t1))
    fixed.push_back(dyn.to_float(exact_numeric(b)));
  std::size_t next = 0;
  StateBreakpoints kinks(model, forces, dyn);
  Vector kink_values = kinks.active() ? kinks.values(p.state) : Vector{};
  const auto stopped = [&](const StepPoint& root) {
    emit(root);
    gbs.stats.stopped = true;
    gbs.stats.stop_time = root.t.to_double();
    gbs.stats.stop_bound = level.bound();
    return gbs.stats;
  };
  try {
    for (int k = 1; k <= grid.steps; ++k) {
      const numeric target = dyn.to_float(exact_numeric(grid.at(k)));
      while (p.t < target) {
        if (gbs.stats.steps >= options.max_steps)
          fail(p.t, "the integrator took more steps than its limit");
        while (next < fixed.size() && !(fixed[next] > p.t)) ++next;
        numeric end = next < fixed.size() && fixed[next] < target ? fixed[next] : target;
        const StepPoint previous = p;
        const Extrapolation before = gbs;
        try {
          numeric g_new, rate_new;
          for (int tries = 0;; ++tries) {
            if (stop.active() && stop.has_rate()) {
              const double limit = stop_limit(g, g_rate);
              if (limit < (end - p.t).to_double()) end = dyn.to_float(p.t + exact_numeric(limit));
            }
            gbs.step(p, end);
            if (kinks.active()) {
              const Vector v = kinks.values(p.state);
              StepPoint at =
                  kinks.first_crossing(before, previous, kink_values, p, v, root_tolerance);
              if (at.t < p.t) p = std::move(at);
            }
            if (!stop.active()) break;
            g_new = stop.value_and_rate(p.state, &rate_new);
            // The limit at the step's end too: else the step again, shorter.
            const double h = (p.t - previous.t).to_double();
            if (!stop.has_rate() || stop_limit(g_new, rate_new) >= h || tries >= 40) break;
            end = dyn.to_float(previous.t +
                               exact_numeric(std::min(stop_limit(g_new, rate_new), h / 2)));
            p = previous;
            gbs.restore_controller(before);
          }
          if (kinks.active()) kink_values = kinks.values(p.state);
          if (!stop.active()) continue;
          g_scale = std::max(g_scale, bounded(g_new));
          const numeric l = dyn.to_float(exact_numeric(level.level()));
          if ((g - l).is_negative() && !(g_new - l).is_negative())
            return stopped(find_root(before, stop, l, previous, g, p, g_new, root_tolerance));
          // A local maximum inside the step (g' from + to -) that reaches 0: the first crossing
          // lies before it.
          if (stop.has_rate() && (g - l).is_negative() && g_rate.is_positive() &&
              rate_new.is_negative()) {
            const auto rate = [&](const ReferenceMotionState& st) { return stop.rate(st); };
            const StepPoint top =
                locate_root(before, rate, previous, g_rate, p, rate_new, root_tolerance);
            const numeric g_top = stop(top.state);
            if (!(g_top - l).is_negative())
              return stopped(find_root(before, stop, l, previous, g, top, g_top, root_tolerance));
          }
          level.see(g_new.is_negative());
          g = g_new;
          g_rate = rate_new;
        } catch (const StopWhenError&) {
          throw;
        } catch (const AnalysisError& e) {
          fail(p.t, e.what());
        }
      }
      emit(p);
    }
  } catch (const Interrupted&) {
    throw AnalysisError(file + ": interrupted at " + format_time(p.t.to_double()));
  }
  return gbs.stats;
}

}  // namespace kinegen::codegen
