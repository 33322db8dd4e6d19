// BlockEmitter (block_emitter.hpp): the position of explicit, guarded and Newton blocks, and
// the Newton policy's checks as the generated loops print them (kernels/newton.hpp).

#include <algorithm>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "block_emitter.hpp"

namespace kinegen::codegen::emit_detail {

// Blocks [b0, b1).
void BlockEmitter::position_body(std::ostringstream& os, FunctionPrinter& pr, int b0, int b1) {
  const std::string in = kIn;
  for (std::size_t bi = b0; bi < static_cast<std::size_t>(b1); ++bi) {
    const BlockPlan& plan = st_.plans[bi];
    const Block& b = plan.block;
    const int f = pos_first_[bi];
    os << in << "// " << block_label(bi) << ": " << block_comment(b, to_string(plan.kind)) << "\n";
    if (roll_of_[bi] >= 0) {
      call_rolled(os, bi, "position", "q, t, p, o, report, trig, block_signs", true);
      continue;
    }
    bind_earlier_trig(os, pr, bi);
    if (plan.torn()) {
      std::vector<std::string> tears;
      for (int c : plan.tears) tears.push_back("q[" + idx(c) + "]");
      os << in << "// Torn: Newton on " << join(tears) << "; " << plan.assigned.size()
         << " coordinates assigned in order from them, " << plan.residuals.size()
         << " residual rows.\n";
    }
    const int n_out = (bi + 1 < st_.plans.size() ? pos_first_[bi + 1] : pos_end_) - f;
    std::vector<int> outputs(n_out);
    for (int o = 0; o < n_out; ++o) outputs[o] = f + o;
    if (plan.kind == BlockKind::kExplicit || plan.kind == BlockKind::kExplicitGuarded) {
      explicit_block(os, pr, bi, outputs);
      continue;
    }
    if (torn_split(bi)) {
      torn_position(os, pr, bi, torn_parts_[bi].rotated);
      continue;
    }
    // Terms that do not read the block's own coordinates are computed once, before the loop
    // (with lazy sin and cos: after the block's own, so that the search skips those).
    std::vector<int> rotated;
    if (lazy_trig_) {
      rotated = declare_rotations(os, pr, b);
      declare_needed_trig(os, pr, outputs);
    }
    for (int o = 0; o < n_out; ++o)
      pr.ensure(out(f + o), os, in, [&](int id) { return level_[id] < static_cast<int>(bi); });
    if (!lazy_trig_) rotated = declare_rotations(os, pr, b);
    if (plan.torn()) {
      torn_position(os, pr, bi, rotated);
      continue;
    }
    newton_block(os, pr, bi, n_out, rotated);
  }
}

// An explicit block (q = its output) or a guarded one (q = -b / c, c checked), then sin and
// cos of its coordinate when the function needs them.
void BlockEmitter::explicit_block(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                                  const std::vector<int>& outputs) {
  const std::string in = kIn;
  const BlockPlan& plan = st_.plans[bi];
  const Block& b = plan.block;
  const int f = pos_first_[bi];
  if (lazy_trig_) declare_needed_trig(os, pr, outputs);
  if (plan.kind == BlockKind::kExplicit) {
    pr.ensure(out(f), os, in);
    os << in << ref("q", b.cols[0]) << " = " << pr.text(out(f)) << ";\n";
    declare_trig(os, pr, b.cols[0], false);
    return;
  }
  pr.ensure(out(f), os, in);
  pr.ensure(out(f + 1), os, in);
  os << in << "{\n"
     << in << "  const T _c = " << pr.text(out(f)) << ";\n"
     << in
     << "  if (!(_mag(_c) > 0)) return _fail(report, _mag(_c) == 0 ? _kStatusSingular : "
        "_kStatusNonFinite, "
     << block_id(bi) << ");\n"
     << in << "  " << ref("q", b.cols[0]) << " = -(" << pr.text(out(f + 1)) << ") / _c;\n"
     << in << "}\n";
  declare_trig(os, pr, b.cols[0], false);
  guarded_condition(os, pr, bi);
}

// A Newton block's loop (its n_out outputs: the k residuals, then the k x k Jacobian), with
// the sin and cos of the `rotated` coordinates kept current, and its verdict.
void BlockEmitter::newton_block(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                                int n_out, const std::vector<int>& rotated) {
  const std::string in = kIn, in2 = in + "  ";
  const Block& b = st_.plans[bi].block;
  const int f = pos_first_[bi];
  const int k = static_cast<int>(b.rows.size());
  const std::string bs = idx(static_cast<int>(bi));
  newton_declare(os, bi, b.cols);
  os << in << "R _st" << bs << " = 0;\n";
  os << in << "for (int _it = 1;; ++_it) {\n";
  pr.open_scope();
  for (int o = 0; o < n_out; ++o) pr.ensure(out(f + o), os, in2);
  std::vector<std::string> r, a;
  for (int o = 0; o < k; ++o) r.push_back(pr.text(out(f + o)));
  for (int o = k; o < n_out; ++o) a.push_back(pr.text(out(f + o)));
  os << in2 << "T _r[" << k << "] = {" << join(r) << "};\n";
  newton_solve(os, in2, bi, k, a);
  os << in2 << "R _step = 0, _qs = 0;\n" << in2 << "bool _small = true;\n";
  for (int i = 0; i < k; ++i) {
    const int c = b.cols[i];
    update(os, in2, rotated, c, ref("q", c) + " - _r[" + idx(i) + "]");
    os << in2 << "_step = std::max(_step, _mag(_r[" << i << "])" << inv_scale(c) << ");\n";
    step_criterion(os, in2, c, i);
  }
  os << in2 << "if (!_finite(_step)) return _fail(report, _kStatusNonFinite, " << block_id(bi)
     << ", _it);\n";
  linear_count(os, in2, bs, "_step");
  newton_stop(os, in2, bi, k, {"_st" + bs + " = _step;", "break;"});
  pr.close_scope();
  os << in << "}\n";
  std::vector<int> rows;
  for (int o = 0; o < k; ++o) rows.push_back(f + o);
  newton_finish(os, pr, bi, rows, "_st" + bs);
}

// |output o| as an entry of Phi_q's column col, in the column's units (lengths times their
// coordinate scale), for the condition checks.
std::string BlockEmitter::scaled_entry(FunctionPrinter& pr, int col, int o) {
  return "_mag(" + pr.text(out(o)) + ")" +
         (length_coordinate(col) ? " * R(" + ref("coordinate_scales", col) + ")" : "");
}

// A guarded block's coefficient against its row's couplings to earlier blocks, at the solved
// q: the block's condition within all of Phi_q (a coefficient that is small beside them is a
// near-singular Phi_q although it is not zero). Recorded in the report's rcond.
void BlockEmitter::guarded_condition(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi) {
  const BlockOuts& bo = blocks_[bi];
  const int c = st_.plans[bi].block.cols[0];
  std::string m = "_own";
  bool coupled = false;
  for (const auto& [col, o] : bo.coupling[0]) {
    if (out(o) == Program::kZero) continue;
    pr.ensure(out(o), os, kIn);
    m = "std::max(" + m + ", " + scaled_entry(pr, col, o) + ")";
    coupled = true;
  }
  if (!coupled || out(bo.jbb[0]) == Program::kZero) return;
  pr.ensure(out(bo.jbb[0]), os, kIn);
  const std::string b = block_id(bi);
  os << kIn << "{\n"
     << kIn << "  const R _own = " << scaled_entry(pr, c, bo.jbb[0]) << ";\n"
     << kIn << "  const R _rc = _own / " << m << ";\n"
     << kIn << "  if (!(_rc > o.min_rcond)) return _fail(report, _kStatusSingular, " << b << ");\n"
     << kIn << "  report.rcond = std::min(report.rcond, _rc);\n"
     << kIn << "}\n";
}

// Newton blocks check what the dense path checks (kernels/newton.hpp): before the loop, the
// state its last iteration leaves for the recheck: the row scales (_rmax), the columns'
// scales (_d: lengths times length_scale), the scaled |q| sum, the condition estimate and
// the determinant's sign of the last factorization, the iteration count and whether the step
// criterion held.
void BlockEmitter::newton_declare(std::ostringstream& os, std::size_t bi,
                                  const std::vector<int>& cols) {
  const std::string b = idx(static_cast<int>(bi));
  const int k = static_cast<int>(cols.size());
  std::vector<std::string> d;
  for (int c : cols)
    d.push_back(length_coordinate(c) ? "R(" + ref("coordinate_scales", c) + ")" : "R(1)");
  os << kIn << "R _rmax" << b << "[" << k << "] = {}, _qs" << b << " = 0, _rc" << b << " = 1, _pv"
     << b << " = 0;\n"
     << kIn << "[[maybe_unused]] const R _cs" << b << "[" << k << "] = {" << join(d) << "};\n"
     << kIn << "int _n" << b << " = 0, _sg" << b << " = 1, _nl" << b << " = 0;\n"
     << kIn << "bool _conv" << b << " = false;\n";
}

// The step criterion for block coordinate c (the update in _r[i]), with the rounding
// allowance; adds its scaled |q| to _qs.
void BlockEmitter::step_criterion(std::ostringstream& os, const std::string& in, int c, int i) {
  const std::string scale = inv_scale(c);
  os << in << "_qs += _mag(" << ref("q", c) << ")" << scale << ";\n"
     << in << "_small &= _step_converged(_mag(_r[" << i << "])" << scale << ", _mag(" << ref("q", c)
     << ")" << scale << ", o.tolerance);\n";
}

// Counts the linear steps (the Newton policy's convergence-rate test) in _nl<b>.
void BlockEmitter::linear_count(std::ostringstream& os, const std::string& in, const std::string& b,
                                const std::string& step) {
  os << in << "_nl" << b << " += _linear_step(" << step << ", _pv" << b << ");\n"
     << in << "_pv" << b << " = " << step << ";\n";
}

// The end of an iteration: stop when the step criterion holds (or the fixed budget is
// spent), or at max_iterations; then keep what the recheck needs (`keep`: more of it).
void BlockEmitter::newton_stop(std::ostringstream& os, const std::string& in, std::size_t bi, int k,
                               const std::vector<std::string>& keep) {
  const std::string b = idx(static_cast<int>(bi));
  os << in << "_conv" << b << " = _small;\n"
     << in << "if ((o.fixed_iterations > 0 ? _it >= o.fixed_iterations : _small) ||\n"
     << in << "    _it >= o.max_iterations) {\n"
     << in << "  _n" << b << " = _it;\n"
     << in << "  _qs" << b << " = _qs;\n";
  if (k == 1) {
    os << in << "  _sg" << b << " = _re(_a) < 0 ? -1 : 1;\n";
  } else {
    os << in << "  _rc" << b << " = _lu_rcond<" << k << ">(_a, _piv, _rmax" << b << ", _cs" << b
       << ");\n"
       << in << "  _sg" << b << " = _lu_det_sign<" << k << ">(_a, _piv);\n";
  }
  for (const std::string& line : keep) os << in << "  " << line << "\n";
  os << in << "}\n";
}

// After the loop: the residual rows (outputs) at the final q, scaled by the last row scales,
// and the block's verdict (_newton_end).
void BlockEmitter::newton_finish(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                                 const std::vector<int>& rows, const std::string& step) {
  const std::string b = idx(static_cast<int>(bi));
  for (int o : rows) pr.ensure(out(o), os, kIn);
  std::vector<std::string> r;
  for (int o : rows) r.push_back("_mag(" + pr.text(out(o)) + ")");
  os << kIn << "const R _rr" << b << "[" << rows.size() << "] = {" << join(r) << "};\n"
     << kIn << "const R _res" << b << " = _scaled_max<" << rows.size() << ">(_rr" << b << ", _rmax"
     << b << ");\n";
  // The condition within all of Phi_q: each row's largest scaled entry, couplings to earlier
  // blocks included (_coupled_rcond), at the final q.
  const BlockPlan& plan = st_.plans[bi];
  const std::vector<int>& own = plan.torn() ? plan.residuals : plan.block.rows;
  std::vector<std::string> cm;
  bool coupled = false;
  for (std::size_t i = 0; i < own.size(); ++i) {
    const auto& block_rows = plan.block.rows;
    const auto& coupling =
        blocks_[bi].coupling[std::lower_bound(block_rows.begin(), block_rows.end(), own[i]) -
                             block_rows.begin()];
    std::string m = "_rmax" + b + "[" + idx(static_cast<int>(i)) + "]";
    // A torn block's rows are scaled by their Schur complement, which vanishes where the
    // block is singular: measure them against their own Phi_q entries too.
    for (const auto& [rc, o] : pos_tjac_[bi]) {
      if (rc.first != own[i] || out(o) == Program::kZero) continue;
      pr.ensure(out(o), os, kIn);
      m = "std::max(" + m + ", " + scaled_entry(pr, rc.second, o) + ")";
      coupled = true;
    }
    for (const auto& [c, o] : coupling) {
      if (out(o) == Program::kZero) continue;
      pr.ensure(out(o), os, kIn);
      m = "std::max(" + m + ", " + scaled_entry(pr, c, o) + ")";
      coupled = true;
    }
    cm.push_back(m);
  }
  if (coupled)
    os << kIn << "const R _cm" << b << "[" << own.size() << "] = {" << join(cm) << "};\n"
       << kIn << "_rc" << b << " = _coupled_rcond<" << own.size() << ">(_rc" << b << ", _rmax" << b
       << ", _cm" << b << ");\n";
  os << kIn << "if (!_newton_end(report, " << block_id(bi) << ", _n" << b << ", _conv" << b
     << ", o, " << step << ", _nl" << b << ", _res" << b << ", _qs" << b << ", _rc" << b << ", _sg"
     << b << ", block_signs))\n"
     << kIn << "  return report;\n";
}

// One Newton update inside an iteration: _r[] holds the residuals of a k x k system whose
// matrix is `a` (row-major texts); leaves the step in _r, or reports a singular block.
void BlockEmitter::newton_solve(std::ostringstream& os, const std::string& in, std::size_t bi,
                                int k, const std::vector<std::string>& a) {
  const std::string b = idx(static_cast<int>(bi));
  if (k == 1) {
    os << in << "const T _a = " << a[0] << ";\n"
       << in
       << "if (!(_mag(_a) > 0)) return _fail(report, _mag(_a) == 0 ? _kStatusSingular : "
          "_kStatusNonFinite, "
       << block_id(bi) << ", _it);\n"
       << in << "_rmax" << b << "[0] = _mag(_a) * _cs" << b << "[0];\n"
       << in << "_r[0] /= _a;\n";
    return;
  }
  os << in << "T _a[" << k * k << "] = {" << join(a) << "};\n"
     << in << "_row_max<" << k << ">(_a, _cs" << b << ", _rmax" << b << ");\n"
     << in << "int _piv[" << k << "];\n"
     << in << "const R _ratio = _lu_factor<" << k << ">(_a, _piv);\n"
     << in << "if (!(_ratio > o.singular_pivot_ratio))\n"
     << in << "  return _fail(report, _ratio == _ratio ? _kStatusSingular : _kStatusNonFinite, "
     << block_id(bi) << ", _it);\n"
     << in << "_lu_solve<" << k << ">(_a, _piv, _r);\n";
}

// q[c] = value, keeping the rotated sin and cos of q[c] current.
void BlockEmitter::update(std::ostringstream& os, const std::string& in,
                          const std::vector<int>& rotated, int c, const std::string& value) {
  const bool rotate = std::find(rotated.begin(), rotated.end(), c) != rotated.end();
  const std::string q = ref("q", c);
  if (rotate) os << in << "const T _old" << c << " = " << q << ";\n";
  os << in << q << " = " << value << ";\n";
  if (rotate)
    os << in << "_rotate(_sin" << c << ", _cos" << c << ", " << q << " - _old" << c << ", " << q
       << ");\n";
}

}  // namespace kinegen::codegen::emit_detail
