#include "kinegen/codegen/analysis/block_interpreter.hpp"

#include <algorithm>
#include <cmath>
#include <kinegen/kernels/lu.hpp>
#include <kinegen/kernels/newton.hpp>
#include <kinegen/kernels/trig_cache.hpp>
#include <limits>
#include <map>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "kinegen/codegen/analysis/evaluator.hpp"

namespace kinegen::codegen {

namespace {

// The kernels as the generated model struct has them: static members of one scope.
struct K : kernels::LuKernel, kernels::TrigCacheKernel, kernels::NewtonKernel {};
constexpr int kSingular = K::_kStatusSingular, kNonFinite = K::_kStatusNonFinite;

// f(std::integral_constant<int, n>) for a run-time n in [1, BlockInterpreter::kMaxNewton].
template <int N = 1, class F>
auto with_size(int n, F&& f) {
  if constexpr (N < BlockInterpreter::kMaxNewton) {
    if (n != N) return with_size<N + 1>(n, std::forward<F>(f));
  }
  return f(std::integral_constant<int, N>{});
}

// A sum as the emitter composes its text: terms joined by " + " and " - ", the first one
// negated in place (`-x`, not `0 - x`, so that the sign of a zero is the printed code's).
struct Sum {
  bool empty = true;
  double v = 0;
  void add(double term, bool minus) {
    v = empty ? (minus ? -term : term) : (minus ? v - term : v + term);
    empty = false;
  }
  double value() const { return empty ? 0.0 : v; }  // "T(0)"
};

bool all_finite(const double* v, int n) {
  bool ok = true;
  for (int k = 0; k < n; ++k) ok &= K::_finite(std::abs(v[k]));
  return ok;
}

// The entries of `row` in a block's (row, col) -> output map, in the map's order.
template <class F>
void for_row(const std::map<std::pair<int, int>, int>& entries, int row, F&& f) {
  for (auto e = entries.lower_bound({row, std::numeric_limits<int>::min()});
       e != entries.end() && e->first.first == row; ++e)
    f(e->first.second, e->second);
}

bool is_unit(const Node& n) { return n.kind == OpKind::kConst && (n.value == 1 || n.value == -1); }

}  // namespace

// One step's state: node values with validity flags, the bound sin and cos of each
// coordinate, and the inputs.
struct BlockInterpreter::Run {
  const BlockInterpreter& it;
  const Program& prog;
  std::vector<double> values;
  std::vector<char> valid;
  std::vector<int> stack;
  std::vector<int> trig_coordinate;        // per node: the coordinate whose sin / cos it is, or -1
  std::vector<std::vector<int>> at_level;  // per block: the nodes of that level
  std::vector<double> s, c;                // per coordinate: the bound sin and cos
  std::vector<char> rotated;               // per coordinate: its sin and cos are rotated
  const double* q = nullptr;
  const double* qd = nullptr;
  double t = 0;
  const double* params = nullptr;
  const double* inputs = nullptr;
  // A torn block's sensitivities of its assigned coordinates to its tears, per block:
  // d[j][c] (the emitter's _D<b>_<j>_<c>), and its factored Schur complement.
  std::vector<std::vector<std::vector<double>>> d;
  std::vector<std::vector<double>> a;  // per block: its factored matrix (k x k) or divisor
  std::vector<std::vector<int>> piv;
  std::vector<char> divide;  // per 1 x 1 block: whether its rates are divided by a[b][0]
  std::vector<std::map<int, std::vector<char>>> dependency;  // per torn block: tear_dependency
  // Scratch of torn_schur, rates and torn_rates, kept from call to call so that a step
  // allocates nothing once each has reached its largest size.
  std::vector<double> schur, reduced_rhs;
  std::vector<Sum> texts;

  explicit Run(const BlockInterpreter& interp)
      : it(interp),
        prog(interp.bp_.program),
        values(prog.nodes.size()),
        valid(prog.nodes.size()),
        trig_coordinate(prog.nodes.size(), -1) {
    const BlockProgram& bp = interp.bp_;
    const int nq = static_cast<int>(bp.sin_of.size());
    for (int col = 0; col < nq; ++col) {
      if (bp.sin_of[col] >= 0) trig_coordinate[bp.sin_of[col]] = col;
      if (bp.cos_of[col] >= 0) trig_coordinate[bp.cos_of[col]] = col;
    }
    at_level.resize(interp.st_.plans.size());
    for (std::size_t k = 0; k < prog.nodes.size(); ++k)
      if (bp.level[k] >= 0) at_level[bp.level[k]].push_back(static_cast<int>(k));
    s.assign(nq, 0);
    c.assign(nq, 0);
    rotated.assign(nq, 0);
    const std::size_t nb = interp.st_.plans.size();
    d.resize(nb);
    a.resize(nb);
    piv.resize(nb);
    divide.assign(nb, 0);
    dependency.resize(nb);
    for (std::size_t b = 0; b < nb; ++b)
      if (interp.st_.plans[b].torn())
        dependency[b] = tear_dependency(interp.st_.plans[b], bp.torn_jacobian[b]);
  }

  void invalidate_level(std::size_t b) {
    for (int k : at_level[b]) valid[k] = 0;
  }

  // The value of node id (an output's node; kZero is 0) at the current inputs.
  double value(int id) {
    if (id == Program::kZero) return 0.0;
    if (valid[id]) return values[id];
    stack.push_back(id);
    while (!stack.empty()) {
      const int k = stack.back();
      if (valid[k]) {
        stack.pop_back();
        continue;
      }
      const Node& n = prog.nodes[k];
      if (const int col = trig_coordinate[k]; col >= 0) {
        values[k] = n.kind == OpKind::kSin ? s[col] : c[col];  // the bound _sinC / _cosC
      } else {
        bool ready = true;
        for (int arg : n.args)
          if (!valid[arg]) {
            stack.push_back(arg);
            ready = false;
          }
        if (!ready) continue;
        values[k] = ProgramEvaluator<double>::node_value(prog.nodes, k, values.data(), q, qd, t,
                                                         params, inputs);
      }
      valid[k] = 1;
      stack.pop_back();
    }
    return values[id];
  }
  double out(int output) { return value(prog.outputs[output]); }
  const Node* node_of(int output) const {
    const int id = prog.outputs[output];
    return id == Program::kZero ? nullptr : &prog.nodes[id];
  }

  // add_product: `coefficient * x` appended to a sum, folding +-1; has_x false: the
  // coefficient alone.
  void add_product(Sum& sum, int output, bool has_x, double x) {
    const Node* n = node_of(output);
    if (!n) return;
    if (!has_x) {
      sum.add(out(output), false);
    } else if (is_unit(*n)) {
      sum.add(x, n->value == -1);
    } else {
      sum.add(out(output) * x, false);
    }
  }
  // divide_negated: `-(sum) / coefficient` (negate) or `(sum) / coefficient`.
  double divide_negated(const Sum& sum, int output, bool negate) {
    if (sum.empty) return 0.0;
    const Node& n = *node_of(output);
    const bool one = is_unit(n);
    const bool minus = negate != (one && n.value == -1);
    const double body = minus ? -sum.v : sum.v;
    return one ? body : body / out(output);
  }

  // schur: a torn block's sensitivities of its assigned coordinates to the tears (into dd) and
  // the tears' Jacobian (row-major m x m, into a), from the block's Phi_q entries.
  void torn_schur(std::size_t bi, const std::map<std::pair<int, int>, int>& entries,
                  std::vector<std::vector<double>>& dd, std::vector<double>& a) {
    const BlockPlan& plan = it.st_.plans[bi];
    const std::size_t m = plan.tears.size();
    const auto& dep = dependency[bi];
    for (const auto& [rc, o] : entries) out(o);
    dd.resize(m);
    for (std::vector<double>& row : dd) row.assign(s.size(), 0.0);  // keeps its storage
    const auto row_sum = [&](int row, int skip, std::size_t j) {
      Sum sum;
      for_row(entries, row, [&](int col, int o) {
        if (col == skip || !dep.at(col)[j]) return;
        if (col == plan.tears[j])
          add_product(sum, o, false, 0);
        else
          add_product(sum, o, true, dd[j][col]);
      });
      return sum;
    };
    for (std::size_t j = 0; j < m; ++j)
      for (const auto& [row, col] : plan.assigned)
        if (dep.at(col)[j])
          dd[j][col] = divide_negated(row_sum(row, col, j), entries.at({row, col}), true);
    a.clear();
    for (int row : plan.residuals)
      for (std::size_t j = 0; j < m; ++j) a.push_back(row_sum(row, -1, j).value());
  }

  // solve_rows (and solve_torn_rows): block bi's rates, Phi_q x = nu (velocity) or gamma, less
  // the couplings to earlier blocks' x, with the factorization the motion phase made.
  void rates(std::size_t bi, double* x, bool velocity) {
    const BlockPlan& plan = it.st_.plans[bi];
    const Block& blk = plan.block;
    const BlockRates& bo = it.bp_.rates[bi];
    const int k = static_cast<int>(blk.rows.size());
    const std::vector<int>& rhs = velocity ? bo.nu : bo.gamma;
    texts.assign(k, Sum());
    for (int i = 0; i < k; ++i) {
      Sum& sum = texts[i];
      if (node_of(rhs[i])) sum.add(out(rhs[i]), false);
      for (const auto& [col, o] : bo.coupling[i]) {
        const Node* n = node_of(o);
        if (!n) continue;
        if (is_unit(*n))
          sum.add(x[col], n->value == 1);
        else
          sum.add(out(o) * x[col], true);
      }
    }
    if (plan.torn()) {
      torn_rates(bi, texts, x);
      return;
    }
    if (k == 1) {
      const double v = texts[0].value();
      x[blk.cols[0]] = divide[bi] ? v / a[bi][0] : v;
      return;
    }
    with_size(k, [&](auto size) {
      constexpr int M = decltype(size)::value;
      double v[M];
      for (int i = 0; i < M; ++i) v[i] = texts[i].value();
      K::_lu_solve<M>(a[bi].data(), piv[bi].data(), v);
      for (int i = 0; i < M; ++i) x[blk.cols[i]] = v[i];
      return 0;
    });
  }

  void torn_rates(std::size_t bi, const std::vector<Sum>& texts, double* x) {
    const BlockPlan& plan = it.st_.plans[bi];
    const Block& blk = plan.block;
    const BlockRates& bo = it.bp_.rates[bi];
    const int m = static_cast<int>(plan.tears.size());
    const auto rhs = [&](int row) {
      return texts[std::lower_bound(blk.rows.begin(), blk.rows.end(), row) - blk.rows.begin()];
    };
    const auto is_tear = [&](int col) {
      return std::find(plan.tears.begin(), plan.tears.end(), col) != plan.tears.end();
    };
    // rhs - the row's non-tear block entries times x (but `skip`).
    const auto reduced = [&](int row, int skip) {
      Sum sum;
      for_row(bo.tjac, row, [&](int col, int o) {
        if (col != skip && !is_tear(col)) add_product(sum, o, true, x[col]);
      });
      Sum t = rhs(row);
      if (sum.empty) return t;
      Sum result;
      result.empty = false;
      result.v = t.empty ? -sum.v : t.v - sum.v;
      return result;
    };
    for (const auto& [row, col] : plan.assigned)
      x[col] = divide_negated(reduced(row, col), bo.tjac.at({row, col}), false);
    std::vector<double>& g = reduced_rhs;
    g.clear();
    for (int row : plan.residuals) g.push_back(reduced(row, -1).value());
    if (m == 1) {
      x[plan.tears[0]] = g[0] / a[bi][0];
    } else {
      with_size(m, [&](auto size) {
        K::_lu_solve<decltype(size)::value>(a[bi].data(), piv[bi].data(), g.data());
        return 0;
      });
      for (int j = 0; j < m; ++j) x[plan.tears[j]] = g[j];
    }
    const auto& dep = dependency[bi];
    for (const auto& [row, col] : plan.assigned) {
      Sum sum;
      for (int j = 0; j < m; ++j)
        if (dep.at(col)[j]) sum.add(d[bi][j][col] * x[plan.tears[j]], false);
      if (!sum.empty) x[col] += sum.v;
    }
  }
};

bool BlockInterpreter::supported(const Structure& st) {
  if (!st.order.perfect || st.plans.empty()) return false;
  for (const BlockPlan& plan : st.plans)
    if (plan.newton_size() > kMaxNewton) return false;
  return true;
}

BlockInterpreter::BlockInterpreter(const CompiledModel& model)
    : model_(model), st_(model.structure()), bp_(model.block_program()) {
  if (!supported(st_)) throw std::logic_error("BlockInterpreter: the structure is not supported");
  for (const BlockPlan& plan : st_.plans)
    if (plan.kind == BlockKind::kNewton)
      for (int col : plan.torn() ? plan.tears : plan.block.cols) newton_coordinates_.push_back(col);
  run_ = std::make_unique<Run>(*this);
  reset();
}

BlockInterpreter::~BlockInterpreter() = default;

void BlockInterpreter::reset() {
  trig_.assign(3 * bp_.trig_slots, std::numeric_limits<double>::quiet_NaN());
  signs_.assign(st_.plans.size(), 0);
}

// One solve_step: the position blocks (position_body in step mode: every cached sin and cos
// is bound), then the blocks' factors for the rates (motion_body), as the header's statements.
// A function returning false has put the failure in `report`.
struct BlockInterpreter::Step {
  Step(BlockInterpreter& in, double* q, const Options& o)
      : in(in),
        r(*in.run_),
        q(q),
        o(o),
        scales(in.model_.symbolic().coordinate_scales),
        kinds(in.model_.symbolic().coordinate_kinds) {}

  bool length(int col) const { return kinds[col] != CoordinateKind::kAngle; }
  // |x| in the coordinate's units: `_mag(x) * R(1 / coordinate_scales[c])`, or radians.
  double scaled(double x, int col) const {
    return length(col) ? std::abs(x) * (1 / scales[col]) : std::abs(x);
  }
  // |output o| as an entry of Phi_q's column col, scaled: `_mag(x) * R(coordinate_scales[c])`.
  double scaled_entry(int col, int output) {
    return length(col) ? std::abs(r.out(output)) * scales[col] : std::abs(r.out(output));
  }
  bool fail(int status, int block, int iterations = 0) {
    report = K::_fail(report, status, block, iterations);
    return false;
  }
  // _trig: the coordinate's sin and cos from the cache (declare_trig).
  bool bind_trig(int col) {
    const int slot = in.bp_.trig_slot[col];
    if (slot < 0) return false;
    K::_trig(r.s[col], r.c[col], q[col], in.trig_.data(), slot);
    return true;
  }
  // update: q[c] = value, rotating its sin and cos.
  void update(int col, double v) {
    const double old = q[col];
    q[col] = v;
    if (r.rotated[col]) K::_rotate(r.s[col], r.c[col], q[col] - old, q[col]);
  }

  // Block bi's position.
  bool position(std::size_t bi) {
    const BlockPlan& plan = in.st_.plans[bi];
    const Block& b = plan.block;
    const int f = in.bp_.position_first[bi];
    if (plan.kind == BlockKind::kExplicit) {
      q[b.cols[0]] = r.out(f);
      bind_trig(b.cols[0]);
      return true;
    }
    if (plan.kind == BlockKind::kExplicitGuarded) return guarded(bi);
    for (int col : b.cols)
      if (bind_trig(col)) r.rotated[col] = 1;
    const int m = static_cast<int>((plan.torn() ? plan.tears : b.cols).size());
    return with_size(m, [&](auto size) { return newton<decltype(size)::value>(bi); });
  }

  // A guarded block: q = -b / c, then guarded_condition: the coefficient against its row's
  // couplings, at the solved q.
  bool guarded(std::size_t bi) {
    const Block& b = in.st_.plans[bi].block;
    const int f = in.bp_.position_first[bi];
    const int block = static_cast<int>(bi);
    const double coefficient = r.out(f);
    if (!(std::abs(coefficient) > 0))
      return fail(std::abs(coefficient) == 0 ? kSingular : kNonFinite, block);
    q[b.cols[0]] = -(r.out(f + 1)) / coefficient;
    bind_trig(b.cols[0]);
    const BlockRates& bo = in.bp_.rates[bi];
    const int col = b.cols[0];
    bool coupled = false;
    for (const auto& [c, out] : bo.coupling[0]) coupled |= r.node_of(out) != nullptr;
    if (coupled && r.node_of(bo.jbb[0])) {
      const double own = scaled_entry(col, bo.jbb[0]);
      double m = own;
      for (const auto& [c, out] : bo.coupling[0])
        if (r.node_of(out)) m = std::max(m, scaled_entry(c, out));
      const double rc = own / m;
      if (!(rc > o.min_rcond)) return fail(kSingular, block);
      report.rcond = std::min(report.rcond, rc);
    }
    return true;
  }

  // What a Newton loop leaves for newton_finish.
  template <int M>
  struct NewtonEnd {
    double rmax[M], qs = 0, rc = 1, step = 0;
    int n = 0, sign = 1, linear_steps = 0;
    bool conv = false;
  };

  // A Newton (or torn) block of M unknowns: the loop, then newton_finish.
  template <int M>
  bool newton(std::size_t bi) {
    const BlockPlan& plan = in.st_.plans[bi];
    const std::vector<int>& cols = plan.torn() ? plan.tears : plan.block.cols;
    const int f = in.bp_.position_first[bi];
    const int block = static_cast<int>(bi);
    NewtonEnd<M> end;
    double cs[M];
    for (int i = 0; i < M; ++i) cs[i] = length(cols[i]) ? scales[cols[i]] : 1.0;
    double prev = 0;
    bool stop = false;
    const int n_assigned = static_cast<int>(plan.assigned.size());
    const int first_residual = f + n_assigned;
    for (int iter = 1;; ++iter) {
      r.invalidate_level(bi);
      if (plan.torn()) {
        for (int j = 0; j < n_assigned; ++j) update(plan.assigned[j].second, r.out(f + j));
        if (stop) break;
      }
      double res[M], jac[M * M];
      for (int i = 0; i < M; ++i) res[i] = r.out(first_residual + i);
      if (plan.torn()) {
        r.torn_schur(bi, in.bp_.torn_jacobian[bi], r.d[bi], r.schur);
        for (int i = 0; i < M * M; ++i) jac[i] = r.schur[i];
      } else {
        for (int i = 0; i < M * M; ++i) jac[i] = r.out(f + M + i);
      }
      // newton_solve
      int piv[M];
      if constexpr (M == 1) {
        const double a = jac[0];
        if (!(std::abs(a) > 0)) return fail(std::abs(a) == 0 ? kSingular : kNonFinite, block, iter);
        end.rmax[0] = std::abs(a) * cs[0];
        res[0] /= a;
      } else {
        K::_row_max<M>(jac, cs, end.rmax);
        const double ratio = K::_lu_factor<M>(jac, piv);
        if (!(ratio > o.singular_pivot_ratio))
          return fail(ratio == ratio ? kSingular : kNonFinite, block, iter);
        K::_lu_solve<M>(jac, piv, res);
      }
      double step = 0, qs = 0;
      bool small = true;
      for (int i = 0; i < M; ++i) {
        const int col = cols[i];
        update(col, q[col] - res[i]);
        step = std::max(step, scaled(res[i], col));
        qs += scaled(q[col], col);
        small &= K::_step_converged(scaled(res[i], col), scaled(q[col], col), o.tolerance);
      }
      if (!K::_finite(step)) return fail(kNonFinite, block, iter);
      end.linear_steps += K::_linear_step(step, prev);  // linear_count
      prev = step;
      end.conv = small;
      if ((o.fixed_iterations > 0 ? iter >= o.fixed_iterations : small) ||
          iter >= o.max_iterations) {
        end.n = iter;
        end.qs = qs;
        if constexpr (M == 1) {
          end.sign = jac[0] < 0 ? -1 : 1;
        } else {
          end.rc = K::_lu_rcond<M>(jac, piv, end.rmax, cs);
          end.sign = K::_lu_det_sign<M>(jac, piv);
        }
        end.step = step;
        if (!plan.torn()) break;
        stop = true;  // a torn block assigns from the final tears first
      }
    }
    return newton_finish<M>(bi, end);
  }

  // newton_finish: the residual rows at the final q, the condition within all of Phi_q
  // (_coupled_rcond) and the verdict (_newton_end).
  template <int M>
  bool newton_finish(std::size_t bi, NewtonEnd<M>& end) {
    const BlockPlan& plan = in.st_.plans[bi];
    const Block& b = plan.block;
    const int first_residual = in.bp_.position_first[bi] + static_cast<int>(plan.assigned.size());
    r.invalidate_level(bi);
    double rr[M];
    for (int i = 0; i < M; ++i) rr[i] = std::abs(r.out(first_residual + i));
    const double residual = K::_scaled_max<M>(rr, end.rmax);
    const BlockRates& bo = in.bp_.rates[bi];
    const std::vector<int>& own = plan.torn() ? plan.residuals : b.rows;
    bool coupled = false;
    double cm[M];
    for (int i = 0; i < M; ++i) {
      const auto& coupling =
          bo.coupling[std::lower_bound(b.rows.begin(), b.rows.end(), own[i]) - b.rows.begin()];
      cm[i] = end.rmax[i];
      for_row(in.bp_.torn_jacobian[bi], own[i], [&](int col, int out) {
        if (!r.node_of(out)) return;
        cm[i] = std::max(cm[i], scaled_entry(col, out));
        coupled = true;
      });
      for (const auto& [col, out] : coupling) {
        if (!r.node_of(out)) continue;
        cm[i] = std::max(cm[i], scaled_entry(col, out));
        coupled = true;
      }
    }
    if (coupled) end.rc = K::_coupled_rcond<M>(end.rc, end.rmax, cm);
    return K::_newton_end(report, static_cast<int>(bi), end.n, end.conv, o, end.step,
                          end.linear_steps, residual, end.qs, end.rc, end.sign, in.signs_.data());
  }

  // Block bi's factors for the rates (a 1 x 1 block's divisor, an LU, a torn block's Schur
  // complement), then its velocity.
  bool rates(std::size_t bi, double* qd) {
    const BlockPlan& plan = in.st_.plans[bi];
    const BlockRates& bo = in.bp_.rates[bi];
    const int k = static_cast<int>(plan.block.rows.size());
    const int block = static_cast<int>(bi);
    std::vector<double>& a = r.a[bi];
    std::vector<int>& piv = r.piv[bi];
    if (plan.torn()) {
      r.torn_schur(bi, bo.tjac, r.d[bi], a);
    } else if (k == 1) {
      const Node* n = r.node_of(bo.jbb[0]);
      a.assign(1, r.out(bo.jbb[0]));
      r.divide[bi] = !(n->kind == OpKind::kConst && n->value == 1);
      if (n->kind != OpKind::kConst && !(std::abs(a[0]) > 0))
        return fail(std::abs(a[0]) == 0 ? kSingular : kNonFinite, block);
      r.rates(bi, qd, true);
      return true;
    } else {
      a.resize(k * k);
      for (int i = 0; i < k * k; ++i) a[i] = r.out(bo.jbb[i]);
    }
    const int m = static_cast<int>(plan.torn() ? plan.tears.size() : k);
    piv.resize(m);
    if (m == 1) {
      r.divide[bi] = 1;
      if (!(std::abs(a[0]) > 0)) return fail(std::abs(a[0]) == 0 ? kSingular : kNonFinite, block);
    } else {
      const double ratio = with_size(
          m, [&](auto size) { return K::_lu_factor<decltype(size)::value>(a.data(), piv.data()); });
      if (!(ratio > o.singular_pivot_ratio))
        return fail(ratio == ratio ? kSingular : kNonFinite, block);
    }
    r.rates(bi, qd, true);
    return true;
  }

  BlockInterpreter& in;
  Run& r;
  double* q;
  const Options& o;
  const std::vector<double>& scales;
  const std::vector<CoordinateKind>& kinds;
  Report report;
};

BlockInterpreter::Report BlockInterpreter::solve_step(double* q, double t, double* qd, double* qdd,
                                                      const Options& o) {
  Run& r = *run_;
  std::fill(r.valid.begin(), r.valid.end(), 0);
  std::fill(r.rotated.begin(), r.rotated.end(), 0);
  r.q = q;
  r.qd = qd;
  r.t = t;
  r.params = model_.params().data();
  r.inputs = inputs_;
  const int nq = model_.nq();
  Step step(*this, q, o);
  phase_ = Phase::kPosition;
  for (std::size_t bi = 0; bi < st_.plans.size(); ++bi)
    if (!step.position(bi)) return step.report;
  if (!all_finite(q, nq)) return K::_fail(step.report, kNonFinite, -1);
  phase_ = Phase::kVelocity;
  // Velocity and acceleration (motion_body, the trig cache's values still bound).
  for (std::size_t bi = 0; bi < st_.plans.size(); ++bi)
    if (!step.rates(bi, qd)) return step.report;
  if (!all_finite(qd, nq)) return K::_fail(step.report, kNonFinite, -1);
  phase_ = Phase::kAcceleration;
  for (std::size_t bi = 0; bi < st_.plans.size(); ++bi) r.rates(bi, qdd, false);
  if (!all_finite(qdd, nq)) return K::_fail(step.report, kNonFinite, -1);
  return step.report;
}

}  // namespace kinegen::codegen
