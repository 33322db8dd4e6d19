// BlockEmitter (block_emitter.hpp): velocity and acceleration block by block (Phi_q x = nu,
// gamma), the factorizations they share and the factors solve_step keeps for solve_forces.

#include <algorithm>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "block_emitter.hpp"

namespace kinegen::codegen::emit_detail {

// Block bi's k x k matrix `a` for the rates, kept as _a<bi> (k = 1: the divisor) or factored
// into _a<bi>/_piv<bi>; reports a singular block.
void BlockEmitter::factor(std::ostringstream& os, std::size_t bi, int k,
                          const std::vector<std::string>& a) {
  const std::string in = kIn, b = idx(static_cast<int>(bi));
  if (k == 1) {
    os << in << "const T _a" << b << " = " << a[0] << ";\n"
       << in << "if (!(_mag(_a" << b << ") > 0)) return _fail(report, _mag(_a" << b
       << ") == 0 ? _kStatusSingular : _kStatusNonFinite, " << block_id(bi) << ");\n";
    save_factors(os, bi, k);
    return;
  }
  os << in << "T _a" << b << "[" << k * k << "] = {" << join(a) << "};\n"
     << in << "int _piv" << b << "[" << k << "];\n"
     << in << "const R _ratio" << b << " = _lu_factor<" << k << ">(_a" << b << ", _piv" << b
     << ");\n"
     << in << "if (!(_ratio" << b << " > o.singular_pivot_ratio))\n"
     << in << "  return _fail(report, _ratio" << b << " == _ratio" << b
     << " ? _kStatusSingular : _kStatusNonFinite, " << block_id(bi) << ");\n";
  save_factors(os, bi, k);
}

// In solve_step: block bi's k x k factors (and a torn block's tear sensitivities, _D) into
// StepFactors.
void BlockEmitter::save_factors(std::ostringstream& os, std::size_t bi, int k) {
  if (!saving_ || !kept_factors(bi)) return;
  const FactorLayout l = factor_layout(st_);
  const BlockPlan& plan = st_.plans[bi];
  const std::string in = kIn, b = idx(static_cast<int>(bi));
  os << in << "if (factors) {\n";
  if (k == 1) {
    os << in << "  factors->a[" << l.a_begin[bi] << "] = _a" << b << ";\n";
  } else {
    os << in << "  std::copy(_a" << b << ", _a" << b << " + " << k * k << ", factors->a + "
       << l.a_begin[bi] << ");\n"
       << in << "  std::copy(_piv" << b << ", _piv" << b << " + " << k << ", factors->piv + "
       << l.piv_begin[bi] << ");\n";
  }
  if (plan.torn()) {
    const auto dep = tear_dependency(bi);
    // The sensitivities are locals, or an array when the block is split into parts.
    const SensitivityName d_name =
        torn_split(bi) ? sensitivity_array(bi, "_D" + b) : sensitivity_locals(bi, "_D" + b + "_");
    int e = l.d_begin[bi];
    for (std::size_t a = 0; a < plan.assigned.size(); ++a)
      for (int j = 0; j < k; ++j, ++e)
        os << in << "  factors->d[" << e << "] = "
           << (dep.at(plan.assigned[a].second)[j] ? d_name(j, static_cast<int>(a))
                                                  : std::string("T(0)"))
           << ";\n";
  }
  os << in << "}\n";
}

// A torn block's rows (or coordinates) in its rate solve's order: the assigned ones, then
// the residual rows (the tears); another block's as in the structure tables.
std::vector<int> BlockEmitter::torn_order(std::size_t bi, bool rows) const {
  const BlockPlan& plan = st_.plans[bi];
  if (!plan.torn()) return rows ? plan.block.rows : plan.block.cols;
  std::vector<int> v;
  for (const auto& [r, c] : plan.assigned) v.push_back(rows ? r : c);
  for (int x : rows ? plan.residuals : plan.tears) v.push_back(x);
  return v;
}

// Blocks [b0, b1); checks: end with the finite checks of qd and qdd.
void BlockEmitter::motion_body(std::ostringstream& os, FunctionPrinter& pr, bool velocity,
                               bool acceleration, int b0, int b1, bool checks) {
  const std::string in = kIn;
  divisor_.assign(blocks_.size(), "");
  // With repeated blocks each block is solved for velocity and then acceleration before the
  // next (a repeated block's function does both): a block's gamma reads only its own and
  // earlier blocks' qd and earlier blocks' qdd.
  const bool interleave = !rolls_.empty();
  for (std::size_t bi = b0; bi < static_cast<std::size_t>(b1); ++bi) {
    const BlockOuts& bo = blocks_[bi];
    const int k = static_cast<int>(st_.plans[bi].block.rows.size());
    const std::string b = idx(static_cast<int>(bi));
    os << in << "// " << block_label(bi) << ": " << block_comment(st_.plans[bi].block, "") << "\n";
    if (roll_of_[bi] >= 0) {
      call_rolled(os, bi, motion_name(velocity, acceleration),
                  motion_args(velocity, acceleration, false) + ", " +
                      (motion_trig_ ? "trig" : "static_cast<T*>(nullptr)"),
                  true);
      continue;
    }
    if (torn_split(bi)) {
      const int m = static_cast<int>(st_.plans[bi].tears.size());
      torn_host_trig(os, pr, bi, false);
      os << in << "T _D" << b << "[" << m * st_.plans[bi].assigned.size() << "];\n";
      for (std::size_t p = 0; p < torn_parts_[bi].rates.size(); ++p)
        os << in << "_torn" << b << "_sensitivities_part" << p << "(q, t, p, trig, _sc, _D" << b
           << ");\n";
      for (int row : st_.plans[bi].residuals)
        for (const auto& [rc, o] : row_entries(bo.tjac, row)) pr.ensure(out(o), os, in);
      factor(os, bi, m,
             schur_matrix(pr, bi, bo.tjac, torn_parts_[bi].dependency,
                          sensitivity_array(bi, "_D" + b)));
      if (velocity) solve_rows(os, pr, bi, bo.nu, "qd");
      if (interleave && acceleration) solve_rows(os, pr, bi, bo.gamma, "qdd");
      continue;
    }
    if (motion_trig_) declare_motion_trig(os, pr, bi, velocity, acceleration);
    if (st_.plans[bi].torn()) {
      const int m = static_cast<int>(st_.plans[bi].tears.size());
      factor(os, bi, m, schur(os, pr, bi, bo.tjac, in, "_D" + b + "_"));
      if (velocity) solve_rows(os, pr, bi, bo.nu, "qd");
      if (interleave && acceleration) solve_rows(os, pr, bi, bo.gamma, "qdd");
      continue;
    }
    for (int id : bo.jbb) pr.ensure(out(id), os, in);
    if (k == 1) {
      const int id = out(bo.jbb[0]);
      const Node& n = prog_.nodes[id];
      if (n.kind == OpKind::kConst) {
        divisor_[bi] = n.value == 1 ? "" : pr.atom_text(id);
      } else {
        factor(os, bi, 1, {pr.text(id)});
        divisor_[bi] = "_a" + b;
      }
    } else {
      std::vector<std::string> a;
      for (int id : bo.jbb) a.push_back(pr.text(out(id)));
      factor(os, bi, k, a);
    }
    if (velocity) solve_rows(os, pr, bi, bo.nu, "qd");
    if (interleave && acceleration) solve_rows(os, pr, bi, bo.gamma, "qdd");
  }
  if (velocity && checks) finite_check(os, "qd");
  if (acceleration) {
    for (std::size_t bi = b0; bi < static_cast<std::size_t>(b1) && !interleave; ++bi)
      solve_rows(os, pr, bi, blocks_[bi].gamma, "qdd");
    if (checks) finite_check(os, "qdd");
  }
}

void BlockEmitter::solve_rows(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                              const std::vector<int>& rhs, const char* var) {
  const Block& blk = st_.plans[bi].block;
  const int k = static_cast<int>(blk.rows.size());
  const std::string in = kIn;
  if (torn_split(bi)) {
    solve_torn_rows_split(os, pr, bi, rhs, var);
    return;
  }
  std::vector<std::string> texts;
  for (int i = 0; i < k; ++i) texts.push_back(rate_rhs(os, pr, bi, rhs, var, i));
  if (st_.plans[bi].torn()) {
    solve_torn_rows(os, pr, bi, texts, var);
    return;
  }
  if (k == 1) {
    const std::string& d = divisor_[bi];
    os << in << ref(var, blk.cols[0]) << " = "
       << (d.empty() ? texts[0] : "(" + texts[0] + ") / " + d) << ";\n";
    return;
  }
  const std::string b = idx(static_cast<int>(bi));
  os << in << "{\n"
     << in << "  T _x[" << k << "] = {" << join(texts) << "};\n"
     << in << "  _lu_solve<" << k << ">(_a" << b << ", _piv" << b << ", _x);\n";
  for (int i = 0; i < k; ++i) os << in << "  " << ref(var, blk.cols[i]) << " = _x[" << i << "];\n";
  os << in << "}\n";
}

// Row i of block bi's rates: rhs minus its couplings to earlier blocks' `var`.
std::string BlockEmitter::rate_rhs(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                                   const std::vector<int>& rhs, const char* var, std::size_t i) {
  const BlockOuts& bo = blocks_[bi];
  const std::string in = kIn;
  const int rid = out(rhs[i]);
  pr.ensure(rid, os, in);
  for (const auto& [c, o] : bo.coupling[i]) pr.ensure(out(o), os, in);
  std::string s = rid == Program::kZero ? "" : pr.text(rid);
  for (const auto& [c, o] : bo.coupling[i]) {
    const int id = out(o);
    const Node& n = prog_.nodes[id];
    const std::string x = ref(var, c);
    if (n.kind == OpKind::kConst && (n.value == 1 || n.value == -1)) {
      const bool minus = n.value == 1;
      s += s.empty() ? (minus ? "-" + x : x) : (minus ? " - " : " + ") + x;
    } else {
      s += (s.empty() ? "-" : " - ") + pr.atom_text(id) + "*" + x;
    }
  }
  return s.empty() ? "T(0)" : s;
}

}  // namespace kinegen::codegen::emit_detail
