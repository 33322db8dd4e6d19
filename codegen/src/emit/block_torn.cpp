// BlockEmitter (block_emitter.hpp): torn blocks: Newton on the tears, the assigned
// coordinates' sensitivities, the Schur complement, their rates and the parts of a split one.

#include <algorithm>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "block_emitter.hpp"

namespace kinegen::codegen::emit_detail {

// The private functions of the split torn blocks (split_blocks), called in order from the
// blocks' Newton loops and rates: each takes a run of the assigned coordinates.
void BlockEmitter::emit_torn_parts(std::ostringstream& os, bool velocity, bool acceleration) {
  if (!uses_sc()) return;
  os << "\n private:\n";
  if (!torn_trig_.empty()) {
    os << "  // Split torn blocks' coordinates with rotated sin and cos: {q index, trig slot};\n"
       << "  // the values live in _sc, 2 per row.\n";
    emit_table(os, "_torn_trig", torn_trig_);
  }
  if (!split_trig_.empty()) {
    os << "  // The other coordinates with a trig slot, {q index, trig slot}: their sin and cos\n"
       << "  // pass between the parts in _sc, 2 per row after _torn_trig's, as the whole\n"
       << "  // function keeps them in its variables.\n";
    emit_table(os, "_split_trig", split_trig_);
  }
  for (std::size_t bi = 0; bi < torn_parts_.size(); ++bi) {
    if (!torn_split(bi)) continue;
    for (std::size_t k = 0; k < torn_parts_[bi].position.size(); ++k)
      emit_torn_position_part(os, bi, k);
    for (std::size_t k = 0; k < torn_parts_[bi].rates.size() && (velocity || acceleration); ++k)
      emit_torn_rate_parts(os, bi, k, velocity, acceleration);
  }
  os << "\n public:\n";
}

// One part function of torn block bi: `_torn<b>_<kind>_part<k>(params)`, its body printed by
// `body` over the assigned coordinates `range`.
void BlockEmitter::emit_torn_part(std::ostringstream& os, std::size_t bi, const std::string& kind,
                                  std::size_t k, const std::pair<int, int>& range,
                                  const std::string& what, const std::string& params,
                                  const std::function<void(FunctionPrinter&)>& body) {
  os << "  // Block " << idx(static_cast<int>(bi)) << ", assigned coordinates " << range.first
     << " to " << range.second - 1 << ": " << what << ".\n"
     << "  template <class T>\n"
     << "  static void _torn" << idx(static_cast<int>(bi)) << "_" << kind << "_part" << k << "("
     << params << ") noexcept {\n";
  if (!used_.empty()) os << kIn << "using " << used_ << ";\n";
  FunctionPrinter pr(prog_, symbols_);
  // Called from the position and from each rate function: only what the position left in
  // _sc is there for certain.
  if (split_sc_) sc_ready_ = sc_in_position_;
  body(pr);
  os << "  }\n";
}

// Part k of torn block bi's position: its assigned coordinates' values, then (when asked)
// their sensitivities to the tears, for the Newton loop's Schur complement.
void BlockEmitter::emit_torn_position_part(std::ostringstream& os, std::size_t bi, std::size_t k) {
  const TornParts& tp = torn_parts_[bi];
  const BlockPlan& plan = st_.plans[bi];
  const int f = pos_first_[bi];
  const std::string in = kIn;
  const auto [a0, a1] = tp.position[k];
  emit_torn_part(os, bi, "position", k, tp.position[k],
                 "their values, then their sensitivities (_d)",
                 std::string("T* q, ") + kTornPartParams +
                     ",\n      [[maybe_unused]] T* _d, [[maybe_unused]] bool _derivatives",
                 [&, a0 = a0, a1 = a1](FunctionPrinter& pr) {
                   std::vector<int> nodes, updated;
                   for (int a = a0; a < a1; ++a) {
                     nodes.push_back(out(f + a));
                     updated.push_back(plan.assigned[a].second);
                     for (const auto& [rc, o] : row_entries(pos_tjac_[bi], plan.assigned[a].first))
                       nodes.push_back(out(o));
                   }
                   torn_trig(os, pr, bi, nodes, updated);
                   for (int a = a0; a < a1; ++a) {
                     pr.ensure(out(f + a), os, in);
                     update(os, in, tp.rotated, plan.assigned[a].second, pr.text(out(f + a)));
                   }
                   os << in << "if (!_derivatives) return;\n";
                   for (int a = a0; a < a1; ++a)
                     for (const auto& [rc, o] : row_entries(pos_tjac_[bi], plan.assigned[a].first))
                       pr.ensure(out(o), os, in);
                   sensitivities(os, pr, bi, pos_tjac_[bi], tp.dependency, in,
                                 sensitivity_array(bi, "_d"), "", a0, a1);
                 });
}

// Part k of torn block bi's rates: the sensitivities to the tears (_D), the correction
// x += _D x_tears, and qd and qdd with the tears' at zero.
void BlockEmitter::emit_torn_rate_parts(std::ostringstream& os, std::size_t bi, std::size_t k,
                                        bool velocity, bool acceleration) {
  const TornParts& tp = torn_parts_[bi];
  const BlockPlan& plan = st_.plans[bi];
  const BlockOuts& bo = blocks_[bi];
  const std::string in = kIn;
  const auto row_of = [&](int r) {
    const auto& rows = plan.block.rows;
    return std::lower_bound(rows.begin(), rows.end(), r) - rows.begin();
  };
  const auto [a0, a1] = tp.rates[k];
  emit_torn_part(os, bi, "sensitivities", k, tp.rates[k], "their sensitivities to the tears (_D)",
                 std::string("[[maybe_unused]] const T* q, ") + kTornPartParams + ", T* _D",
                 [&, a0 = a0, a1 = a1](FunctionPrinter& pr) {
                   std::vector<int> nodes;
                   for (int a = a0; a < a1; ++a)
                     for (const auto& [rc, o] : row_entries(bo.tjac, plan.assigned[a].first))
                       nodes.push_back(out(o));
                   torn_trig(os, pr, bi, nodes, {});
                   for (int id : nodes) pr.ensure(id, os, in);
                   sensitivities(os, pr, bi, bo.tjac, tp.dependency, in,
                                 sensitivity_array(bi, "_D"), "", a0, a1);
                 });
  emit_torn_part(os, bi, "correct", k, tp.rates[k], "x += their sensitivities times the tears' x",
                 "const T* _D, T* x", [&, a0 = a0, a1 = a1](FunctionPrinter&) {
                   correct(os, bi, tp.dependency, sensitivity_array(bi, "_D"), "x", a0, a1);
                 });
  for (const bool acc : {false, true}) {
    if (acc ? !acceleration : !velocity) continue;
    const char* var = acc ? "qdd" : "qd";
    emit_torn_part(
        os, bi, var, k, tp.rates[k], std::string("their ") + var + " with the tears' at zero",
        std::string(acc ? "[[maybe_unused]] const T* q, [[maybe_unused]] const T* qd,\n      "
                        : "[[maybe_unused]] const T* q, ") +
            kTornPartParams + ", T* " + var,
        [&, a0 = a0, a1 = a1, acc, var](FunctionPrinter& pr) {
          const std::vector<int>& rhs = acc ? bo.gamma : bo.nu;
          std::vector<int> nodes;
          for (int a = a0; a < a1; ++a) {
            const int r = plan.assigned[a].first;
            nodes.push_back(out(rhs[row_of(r)]));
            for (const auto& [c, o] : bo.coupling[row_of(r)]) nodes.push_back(out(o));
            for (const auto& [rc, o] : row_entries(bo.tjac, r)) nodes.push_back(out(o));
          }
          torn_trig(os, pr, bi, nodes, {});
          for (int a = a0; a < a1; ++a) {
            const auto [r, c] = plan.assigned[a];
            const std::string text = rate_rhs(os, pr, bi, rhs, var, row_of(r));
            const std::string s = reduced_rhs(pr, bi, text, r, c, var);
            os << in << ref(var, c) << " = "
               << divide_negated(pr, s == "T(0)" ? "" : s, bo.tjac.at({r, c}), false) << ";\n";
          }
        });
  }
}

// Appends `coefficient * x` (a Phi_q output) to a sum's text, folding +-1; x empty: the
// coefficient alone.
void BlockEmitter::add_product(std::string& sum, FunctionPrinter& pr, int output,
                               const std::string& x) {
  const int id = out(output);
  if (id == Program::kZero) return;
  const Node& n = prog_.nodes[id];
  if (x.empty()) {  // the coefficient alone
    sum += (sum.empty() ? "" : " + ") + pr.atom_text(id);
  } else if (n.kind == OpKind::kConst && (n.value == 1 || n.value == -1)) {
    const bool minus = n.value == -1;
    sum += sum.empty() ? (minus ? "-" + x : x) : (minus ? " - " : " + ") + x;
  } else {
    sum += (sum.empty() ? "" : " + ") + pr.atom_text(id) + "*" + x;
  }
}

// `-(sum) / coefficient` for an assigned row's constant coefficient (an output).
std::string BlockEmitter::divide_negated(FunctionPrinter& pr, const std::string& sum, int output,
                                         bool negate) {
  const Node& n = prog_.nodes[out(output)];
  if (sum.empty()) return "T(0)";
  const bool one = n.kind == OpKind::kConst && (n.value == 1 || n.value == -1);
  const bool minus = negate != (one && n.value == -1);
  const std::string body = minus ? "-(" + sum + ")" : "(" + sum + ")";
  return one ? body : body + " / " + pr.atom_text(out(output));
}

// Locals `prefix<j>_<c>` (a whole block), or a caller-owned array (a split torn block).
BlockEmitter::SensitivityName BlockEmitter::sensitivity_locals(std::size_t bi,
                                                               const std::string& prefix) const {
  return [this, bi, prefix](std::size_t j, int a) {
    return prefix + std::to_string(j) + "_" + idx(st_.plans[bi].assigned[a].second);
  };
}

BlockEmitter::SensitivityName BlockEmitter::sensitivity_array(std::size_t bi,
                                                              const std::string& array) const {
  const int n = static_cast<int>(st_.plans[bi].assigned.size());
  return [n, array](std::size_t j, int a) {
    return array + "[" + std::to_string(static_cast<int>(j) * n + a) + "]";
  };
}

// The sum over row r's block coordinates (but `skip`) of Phi_q * dq/dtear_j.
std::string BlockEmitter::row_sum(FunctionPrinter& pr, std::size_t bi,
                                  const std::map<std::pair<int, int>, int>& entries,
                                  const std::map<int, std::vector<char>>& dep,
                                  const SensitivityName& d_name,
                                  const std::map<int, int>& assigned_index, int r, int skip,
                                  std::size_t j) {
  const BlockPlan& plan = st_.plans[bi];
  std::string sum;
  for (const auto& [rc, o] : row_entries(entries, r)) {
    if (rc.second == skip || !dep.at(rc.second)[j]) continue;
    add_product(sum, pr, o,
                rc.second == plan.tears[j] ? "" : d_name(j, assigned_index.at(rc.second)));
  }
  return sum;
}

std::map<int, int> BlockEmitter::assigned_index(std::size_t bi) const {
  std::map<int, int> index;
  const auto& assigned = st_.plans[bi].assigned;
  for (std::size_t a = 0; a < assigned.size(); ++a) index[assigned[a].second] = static_cast<int>(a);
  return index;
}

// Sensitivities of the assigned coordinates plan.assigned[a0..a1) to the tears (dq[c]/dq[tear
// j], from the assigned rows in order: the rows stay satisfied), `declare` name = ...;.
void BlockEmitter::sensitivities(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                                 const std::map<std::pair<int, int>, int>& entries,
                                 const std::map<int, std::vector<char>>& dep, const std::string& in,
                                 const SensitivityName& d_name, const char* declare, int a0,
                                 int a1) {
  const BlockPlan& plan = st_.plans[bi];
  const std::map<int, int> index = assigned_index(bi);
  for (std::size_t j = 0; j < plan.tears.size(); ++j) {
    for (int a = a0; a < a1; ++a) {
      const auto [r, c] = plan.assigned[a];
      if (!dep.at(c)[j]) continue;
      const std::string sum = row_sum(pr, bi, entries, dep, d_name, index, r, c, j);
      os << in << declare << d_name(j, a) << " = "
         << divide_negated(pr, sum, entries.at({r, c}), true) << ";\n";
    }
  }
}

// The tears' Jacobian (the Schur complement): the row-major text of the m x m matrix.
std::vector<std::string> BlockEmitter::schur_matrix(
    FunctionPrinter& pr, std::size_t bi, const std::map<std::pair<int, int>, int>& entries,
    const std::map<int, std::vector<char>>& dep, const SensitivityName& d_name) {
  const BlockPlan& plan = st_.plans[bi];
  const std::map<int, int> index = assigned_index(bi);
  std::vector<std::string> a;
  for (int r : plan.residuals)
    for (std::size_t j = 0; j < plan.tears.size(); ++j) {
      const std::string sum = row_sum(pr, bi, entries, dep, d_name, index, r, -1, j);
      a.push_back(sum.empty() ? "T(0)" : sum);
    }
  return a;
}

// The sensitivities as `prefix<j>_<c>` terms and the Schur complement, for a whole block.
std::vector<std::string> BlockEmitter::schur(std::ostringstream& os, FunctionPrinter& pr,
                                             std::size_t bi,
                                             const std::map<std::pair<int, int>, int>& entries,
                                             const std::string& in, const std::string& prefix) {
  const auto dep = tear_dependency(bi);
  for (const auto& [rc, o] : entries) pr.ensure(out(o), os, in);
  const SensitivityName d_name = sensitivity_locals(bi, prefix);
  sensitivities(os, pr, bi, entries, dep, in, d_name, "const T ", 0,
                static_cast<int>(st_.plans[bi].assigned.size()));
  return schur_matrix(pr, bi, entries, dep, d_name);
}

// Newton on a torn block's tears: each pass assigns the other coordinates from the tears,
// then (unless converged) evaluates the residuals and the tears' Jacobian and updates them.
void BlockEmitter::torn_position(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                                 const std::vector<int>& rotated) {
  const BlockPlan& plan = st_.plans[bi];
  const int m = static_cast<int>(plan.tears.size());
  const int f = pos_first_[bi];
  const int n_assigned = static_cast<int>(plan.assigned.size());
  const std::string in = kIn, in2 = in + "  ", b = idx(static_cast<int>(bi));
  const bool split = torn_split(bi);
  // Split: the parts assign the coordinates and compute their sensitivities (into _d<b>);
  // sin and cos of the block's coordinates live in _sc.
  if (split) torn_host_trig(os, pr, bi, true);
  newton_declare(os, bi, plan.tears);
  os << in << "R _step" << b << " = 0;\n" << in << "bool _stop" << b << " = false;\n";
  if (split) os << in << "T _d" << b << "[" << m * n_assigned << "];\n";
  os << in << "for (int _it = 1;; ++_it) {\n";
  pr.open_scope();
  if (split) {
    for (std::size_t k = 0; k < torn_parts_[bi].position.size(); ++k)
      os << in2 << "_torn" << b << "_position_part" << k << "(q, t, p, trig, _sc, _d" << b
         << ", !_stop" << b << ");\n";
  }
  for (int a = 0; a < n_assigned && !split; ++a) {
    pr.ensure(out(f + a), os, in2);
    update(os, in2, rotated, plan.assigned[a].second, pr.text(out(f + a)));
  }
  os << in2 << "if (_stop" << b << ") break;\n";
  std::vector<std::string> r;
  for (int i = 0; i < m; ++i) {
    pr.ensure(out(f + n_assigned + i), os, in2);
    r.push_back(pr.text(out(f + n_assigned + i)));
  }
  os << in2 << "T _r[" << m << "] = {" << join(r) << "};\n";
  std::vector<std::string> matrix;
  if (split) {
    for (int row : plan.residuals)
      for (const auto& [rc, o] : row_entries(pos_tjac_[bi], row)) pr.ensure(out(o), os, in2);
    matrix = schur_matrix(pr, bi, pos_tjac_[bi], torn_parts_[bi].dependency,
                          sensitivity_array(bi, "_d" + b));
  } else {
    matrix = schur(os, pr, bi, pos_tjac_[bi], in2, "_d");
  }
  newton_solve(os, in2, bi, m, matrix);
  os << in2 << "_step" << b << " = 0;\n" << in2 << "R _qs = 0;\n" << in2 << "bool _small = true;\n";
  for (int i = 0; i < m; ++i) {
    const int c = plan.tears[i];
    update(os, in2, rotated, c, ref("q", c) + " - _r[" + idx(i) + "]");
    os << in2 << "_step" << b << " = std::max(_step" << b << ", _mag(_r[" << i << "])"
       << inv_scale(c) << ");\n";
    step_criterion(os, in2, c, i);
  }
  os << in2 << "if (!_finite(_step" << b << ")) return _fail(report, _kStatusNonFinite, "
     << block_id(bi) << ", _it);\n";
  linear_count(os, in2, b, "_step" + b);
  newton_stop(os, in2, bi, m, {"_stop" + b + " = true;"});
  pr.close_scope();
  os << in << "}\n";
  std::vector<int> rows;
  for (int i = 0; i < m; ++i) rows.push_back(f + n_assigned + i);
  newton_finish(os, pr, bi, rows, "_step" + b);
}

// A torn block's row r: `rhs` minus the row's non-tear block entries times x (other than
// `skip`).
std::string BlockEmitter::reduced_rhs(FunctionPrinter& pr, std::size_t bi, const std::string& rhs,
                                      int r, int skip, const char* var) {
  const BlockPlan& plan = st_.plans[bi];
  const auto is_tear = [&](int c) {
    return std::find(plan.tears.begin(), plan.tears.end(), c) != plan.tears.end();
  };
  std::string sum;
  for (const auto& [rc, o] : row_entries(blocks_[bi].tjac, r))
    if (rc.second != skip && !is_tear(rc.second)) add_product(sum, pr, o, ref(var, rc.second));
  if (sum.empty()) return rhs;
  return rhs == "T(0)" ? "-(" + sum + ")" : rhs + " - (" + sum + ")";
}

// The tears' x from the reduced residual rows g and the Schur complement factored in
// motion_body.
void BlockEmitter::solve_tears(std::ostringstream& os, std::size_t bi,
                               const std::vector<std::string>& g, const char* var) {
  const BlockPlan& plan = st_.plans[bi];
  const int m = static_cast<int>(plan.tears.size());
  const std::string in = kIn, b = idx(static_cast<int>(bi));
  if (m == 1) {
    os << in << ref(var, plan.tears[0]) << " = (" << g[0] << ") / _a" << b << ";\n";
  } else {
    os << in << "{\n"
       << in << "  T _x[" << m << "] = {" << join(g) << "};\n"
       << in << "  _lu_solve<" << m << ">(_a" << b << ", _piv" << b << ", _x);\n";
    for (int j = 0; j < m; ++j)
      os << in << "  " << ref(var, plan.tears[j]) << " = _x[" << j << "];\n";
    os << in << "}\n";
  }
}

// The assigned coordinates a0..a1 corrected by their sensitivities times the tears' x.
void BlockEmitter::correct(std::ostringstream& os, std::size_t bi,
                           const std::map<int, std::vector<char>>& dep,
                           const SensitivityName& d_name, const char* var, int a0, int a1) {
  const BlockPlan& plan = st_.plans[bi];
  for (int a = a0; a < a1; ++a) {
    const int c = plan.assigned[a].second;
    std::string sum;
    for (std::size_t j = 0; j < plan.tears.size(); ++j)
      if (dep.at(c)[j])
        sum += (sum.empty() ? "" : " + ") + d_name(j, a) + "*" + ref(var, plan.tears[j]);
    if (!sum.empty()) os << kIn << ref(var, c) << " += " << sum << ";\n";
  }
}

// A split torn block's rates: the parts' particular solution, the tears in this function,
// then the parts' corrections.
void BlockEmitter::solve_torn_rows_split(std::ostringstream& os, FunctionPrinter& pr,
                                         std::size_t bi, const std::vector<int>& rhs,
                                         const char* var) {
  const BlockPlan& plan = st_.plans[bi];
  const std::string b = idx(static_cast<int>(bi)), v = var;
  const std::size_t parts = torn_parts_[bi].rates.size();
  for (std::size_t k = 0; k < parts; ++k)
    os << kIn << "_torn" << b << "_" << v << "_part" << k << "(q, " << (v == "qdd" ? "qd, " : "")
       << "t, p, trig, _sc, " << v << ");\n";
  std::vector<std::string> g;
  for (int r : plan.residuals) {
    const auto& rows = plan.block.rows;
    const std::size_t i = std::lower_bound(rows.begin(), rows.end(), r) - rows.begin();
    g.push_back(reduced_rhs(pr, bi, rate_rhs(os, pr, bi, rhs, var, i), r, -1, var));
  }
  solve_tears(os, bi, g, var);
  for (std::size_t k = 0; k < parts; ++k)
    os << kIn << "_torn" << b << "_correct_part" << k << "(_D" << b << ", " << v << ");\n";
}

// A torn block's linear system (Phi_q x = rhs on the block): a particular solution with the
// tears at zero through the assigned rows, the tears from the Schur complement factored in
// motion_body, then the assigned coordinates corrected by their sensitivities.
void BlockEmitter::solve_torn_rows(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                                   const std::vector<std::string>& texts, const char* var) {
  const BlockPlan& plan = st_.plans[bi];
  const Block& blk = plan.block;
  const BlockOuts& bo = blocks_[bi];
  const std::string b = idx(static_cast<int>(bi));
  const auto rhs = [&](int r) {
    const auto it = std::lower_bound(blk.rows.begin(), blk.rows.end(), r);
    return texts[it - blk.rows.begin()];
  };
  for (const auto& [r, c] : plan.assigned) {
    const std::string s = reduced_rhs(pr, bi, rhs(r), r, c, var);
    os << kIn << ref(var, c) << " = "
       << divide_negated(pr, s == "T(0)" ? "" : s, bo.tjac.at({r, c}), false) << ";\n";
  }
  std::vector<std::string> g;
  for (int r : plan.residuals) g.push_back(reduced_rhs(pr, bi, rhs(r), r, -1, var));
  solve_tears(os, bi, g, var);
  correct(os, bi, tear_dependency(bi), sensitivity_locals(bi, "_D" + b + "_"), var, 0,
          static_cast<int>(plan.assigned.size()));
}

}  // namespace kinegen::codegen::emit_detail
