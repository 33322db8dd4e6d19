#include "block_solver.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <sstream>

#include "kinegen/codegen/emit/embedded_kernels.hpp"
#include "kinegen/codegen/emit/reserved_names.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "kinegen/codegen/program/partition.hpp"
#include "kinegen/codegen/structure/block_program.hpp"
#include "kinegen/codegen/structure/solver_plan.hpp"
#include "kinegen/codegen/structure/structure.hpp"

#include "printer.hpp"

namespace kinegen::codegen::emit_detail {

std::string block_comment(const Block& b, const char* kind) {
  std::vector<std::string> rows, cols;
  for (int r : b.rows) rows.push_back(idx(r));
  for (int c : b.cols) cols.push_back("q[" + idx(c) + "]");
  return std::string("rows ") + join(rows) + " -> " + join(cols) +
         (*kind ? std::string(" (") + kind + ")" : "");
}

// Where StepFactors keeps each block's factors (offsets, in block order, with one past the
// end): a K x K block's LU in a (none for 1 x 1), a torn block's m x m Schur complement there
// and its assigned coordinates' sensitivities to the tears (assigned x m, row-major) in d; the
// pivots at the block's first place in block_cols.
struct FactorLayout {
  std::vector<int> a_begin{0}, d_begin{0}, piv_begin{0};
};
FactorLayout factor_layout(const Structure& st) {
  FactorLayout l;
  for (const BlockPlan& plan : st.plans) {
    const int k = static_cast<int>(plan.block.rows.size());
    const int m = plan.torn() ? static_cast<int>(plan.tears.size()) : k;
    l.a_begin.push_back(l.a_begin.back() + (m > 1 || plan.torn() ? m * m : 0));
    l.d_begin.push_back(l.d_begin.back() +
                        (plan.torn() ? static_cast<int>(plan.assigned.size()) * m : 0));
    l.piv_begin.push_back(l.piv_begin.back() + k);
  }
  return l;
}

// Position, velocity and acceleration block by block. One program holds every expression the
// block functions need, so each function shares terms (sin and cos of an angle are computed
// once per function) and the full-step function shares them between the phases. Terms are
// printed where first needed; those inside a Newton loop go out of scope with it.
class BlockEmitter {
 public:
  BlockEmitter(const std::vector<CoordinateKind>& kinds, const SymbolTable& symbols,
               const SolverPlan& plan)
      : plan_(plan), symbols_(symbols), kinds_(kinds), lazy_trig_(!plan.repeated.empty()) {}

  int trig_cache_size() const { return 3 * trig_slots_; }
  // The functions of the repeated blocks and their coordinate tables (private members).
  void emit_rolls(std::ostringstream& os, bool velocity, bool acceleration) {
    emit_torn_parts(os, velocity, acceleration);
    if (rolls_.empty()) return;
    os << "\n private:\n";
    for (std::size_t g = 0; g < rolls_.size(); ++g) {
      const RepeatedBlocks& r = rolls_[g];
      const std::string name = "_roll" + idx(static_cast<int>(g));
      os << "\n  // Repeated blocks (" << r.blocks.size() << ", the first is block " << r.blocks[0]
         << "): alike up to the coordinates\n"
         << "  // they read, so each calls the functions below with its row of " << name << "_i\n"
         << "  // (its own coordinates, then the others it reads)"
         << (r.slots[0].empty() ? "" : " and of " + name + "_s (its sin/cos\n  // cache slots)")
         << ".\n";
      emit_table(os, name + "_i", r.coords);
      if (!r.slots[0].empty()) emit_table(os, name + "_s", r.slots);
      // The first block's functions, reading coordinates through its table.
      BlockEmitter e(kinds_, symbols_, *r.alone);
      e.local_.assign(st_.order.col_block.size(), -1);
      e.first_block_ = r.blocks[0];
      for (std::size_t j = 0; j < r.coords[0].size(); ++j)
        e.local_[r.coords[0][j]] = static_cast<int>(j);
      e.emit_rolled_position(os, name);
      if (velocity) e.emit_rolled_motion(os, name, true, false);
      if (acceleration) {
        e.emit_rolled_motion(os, name, false, true);
        e.emit_rolled_motion(os, name, true, true);
      }
    }
    os << "\n public:\n";
  }

  void emit_position(std::ostringstream& os) {
    os << "  // Position: each block in turn, explicit or by Newton on the block alone; q holds\n"
       << "  // the start (the previous solution or a prediction) and receives the solution.\n"
       << "  // trig: optional cache of trig_cache_size values, kept by the caller from call to call\n"
       << "  // (fill it with NaN first), so that sin and cos near the last values are rotations.\n"
       << "  // block_signs: optional, num_blocks entries kept by the caller (zero first): each Newton\n"
       << "  // block's determinant sign is recorded there, and a change fails with status 6.\n"
       << "  template <class T, class U>\n"
       << "  static BlockReport<_real<T>> solve_position(T* q, [[maybe_unused]] T t,\n"
       << "      [[maybe_unused]] const Params& p,\n"
       << "      [[maybe_unused]] const BasicBlockOptions<U>& options,\n"
       << "      [[maybe_unused]] T* trig = nullptr,\n"
       << "      [[maybe_unused]] signed char* block_signs = nullptr) noexcept {\n";
    if (!ranges_.empty()) {
      os << kIn << "using R = _real<T>;\n" << kOptions << kIn << "BlockReport<R> report;\n";
      declare_sc(os, false);
      call_parts(os, "_solve_position_part",
                 "q, t, p, o, report, trig, block_signs" + sc_arg(false));
      finite_check(os, "q");
      os << kIn << "return report;\n  }\n";
      emit_position_parts(os);
      return;
    }
    FunctionPrinter pr(prog_, symbols_);
    prologue(os);
    position_body(os, pr, 0, static_cast<int>(st_.plans.size()));
    finite_check(os, "q");
    os << kIn << "return report;\n  }\n";
  }

  void emit_motion(std::ostringstream& os, bool velocity, bool acceleration) {
    if (velocity && acceleration) {
      os << "  // Velocity (Phi_q qd = nu) and acceleration (Phi_q qdd = gamma) at a solved q,\n"
         << "  // block by block with one factorization per block.\n"
         << "  template <class T, class U>\n"
         << "  static BlockReport<_real<T>> solve_velocity_acceleration([[maybe_unused]] const T* q,\n"
         << "      [[maybe_unused]] T t, [[maybe_unused]] const Params& p, T* qd, T* qdd,\n";
    } else if (velocity) {
      os << "  // Velocity: Phi_q qd = nu at a solved q, block by block.\n"
         << "  template <class T, class U>\n"
         << "  static BlockReport<_real<T>> solve_velocity([[maybe_unused]] const T* q,\n"
         << "      [[maybe_unused]] T t, [[maybe_unused]] const Params& p, T* qd,\n";
    } else {
      os << "  // Acceleration: Phi_q qdd = gamma at a solved q and qd, block by block.\n"
         << "  template <class T, class U>\n"
         << "  static BlockReport<_real<T>> solve_acceleration([[maybe_unused]] const T* q,\n"
         << "      [[maybe_unused]] const T* qd, [[maybe_unused]] T t,\n"
         << "      [[maybe_unused]] const Params& p, T* qdd,\n";
    }
    os << "      [[maybe_unused]] const BasicBlockOptions<U>& options) noexcept {\n";
    if (!ranges_.empty()) {
      const std::string name = motion_name(velocity, acceleration);
      os << kIn << "using R = _real<T>;\n" << kOptions << kIn << "BlockReport<R> report;\n";
      declare_sc(os, true);
      call_parts(os, "_" + name + "_part",
                 motion_args(velocity, acceleration, false) + ", static_cast<T*>(nullptr)" +
                     sc_arg(false) +
                     (parts_save(velocity, acceleration) ? ", static_cast<StepFactors<T>*>(nullptr)"
                                                         : ""));
      if (velocity) finite_check(os, "qd");
      if (acceleration) finite_check(os, "qdd");
      os << kIn << "return report;\n  }\n";
      emit_motion_parts(os, velocity, acceleration);
      return;
    }
    FunctionPrinter pr(prog_, symbols_);
    prologue(os);
    motion_body(os, pr, velocity, acceleration, 0, static_cast<int>(blocks_.size()), true);
    os << kIn << "return report;\n  }\n";
  }

  // The full step: position, then velocity and acceleration, sharing every term.
  void emit_step(std::ostringstream& os) {
    os << "  // A full step: solve_position, then solve_velocity_acceleration, in one function\n"
       << "  // so that terms at the solved q are computed once.\n"
       << "  template <class T, class U>\n"
       << "  static BlockReport<_real<T>> solve_step(T* q, [[maybe_unused]] T t,\n"
       << "      [[maybe_unused]] const Params& p, T* qd, T* qdd,\n"
       << "      [[maybe_unused]] const BasicBlockOptions<U>& options,\n"
       << "      [[maybe_unused]] T* trig = nullptr,\n"
       << "      [[maybe_unused]] signed char* block_signs = nullptr"
       << (step_factors_ ? ",\n      [[maybe_unused]] StepFactors<T>* factors = nullptr" : "")
       << ") noexcept {\n";
    if (!ranges_.empty()) {
      // Split: the parts of solve_position and solve_velocity_acceleration (emitted with them).
      os << kIn << "using R = _real<T>;\n" << kOptions << kIn << "BlockReport<R> report;\n";
      declare_sc(os, false);
      factors_rcond(os, "R(0)");
      call_parts(os, "_solve_position_part",
                 "q, t, p, o, report, trig, block_signs" + sc_arg(false));
      finite_check(os, "q");
      call_parts(os, "_solve_velocity_acceleration_part",
                 motion_args(true, true, false) + ", trig" + sc_arg(false) +
                     (step_factors_ ? ", factors" : ""));
      finite_check(os, "qd");
      finite_check(os, "qdd");
      factors_rcond(os, "report.rcond");
      os << kIn << "return report;\n  }\n";
      return;
    }
    FunctionPrinter pr(prog_, symbols_);
    prologue(os);
    factors_rcond(os, "R(0)");
    const int n = static_cast<int>(st_.plans.size());
    step_mode_ = true;
    position_body(os, pr, 0, n);
    step_mode_ = false;
    finite_check(os, "q");
    motion_trig_ = true;
    saving_ = step_factors_;
    motion_body(os, pr, true, true, 0, n, true);
    saving_ = false;
    motion_trig_ = false;
    factors_rcond(os, "report.rcond");
    os << kIn << "return report;\n  }\n";
  }

  // solve_step keeps its factors for solve_forces (StepFactors, emit_step_factors).
  void keep_step_factors() { step_factors_ = true; }

  // StepFactors and the tables _block_transposed_reusing reads (kernels/block_linear.hpp):
  // where each block's factors are, whether solve_step keeps them (not in a repeated block's
  // function), and each torn block's rows and coordinates in the
  // order of its rate solve (assigned, then residual rows and tears).
  void emit_step_factors(std::ostringstream& os) const {
    const FactorLayout l = factor_layout(st_);
    std::vector<std::string> a_begin, d_begin, kept, tears, rows, cols;
    for (std::size_t bi = 0; bi < st_.plans.size(); ++bi) {
      const BlockPlan& plan = st_.plans[bi];
      a_begin.push_back(idx(l.a_begin[bi]));
      d_begin.push_back(idx(l.d_begin[bi]));
      kept.push_back(kept_factors(bi) ? "1" : "0");
      tears.push_back(idx(static_cast<int>(plan.tears.size())));
      for (int r : torn_order(bi, true)) rows.push_back(idx(r));
      for (int c : torn_order(bi, false)) cols.push_back(idx(c));
    }
    a_begin.push_back(idx(l.a_begin.back()));
    d_begin.push_back(idx(l.d_begin.back()));
    const auto size = [](int n) { return idx(std::max(1, n)); };
    os << "  // The factors of a step's rate solve, kept for solve_forces at the same q and t\n"
       << "  // (solve_step's last argument; kernels/block_linear.hpp): each block's LU (a\n"
       << "  // torn block's: its tears' Schur complement, and in d the assigned\n"
       << "  // coordinates' sensitivities to the tears), and the step's condition estimate.\n"
       << "  // solve_step sets rcond to 0 first and to its report's rcond once it has\n"
       << "  // succeeded, so that solve_forces never uses the factors of a failed step.\n"
       << "  // Caller-owned, fixed size, no constructor work.\n"
       << "  template <class T>\n"
       << "  struct StepFactors {\n"
       << "    T a[" << size(l.a_begin.back()) << "];\n"
       << "    int piv[nq];\n"
       << "    T d[" << size(l.d_begin.back()) << "];\n"
       << "    _real<T> rcond = 0;\n"
       << "  };\n"
       << "  static constexpr std::array<int, num_blocks + 1> factor_begin = {" << join(a_begin)
       << "};\n"
       << "  static constexpr std::array<int, num_blocks> step_factored = {" << join(kept) << "};\n"
       << "  static constexpr std::array<int, num_blocks> block_tears = {" << join(tears) << "};\n"
       << "  static constexpr std::array<int, nc> tear_rows = {" << join(rows) << "};\n"
       << "  static constexpr std::array<int, nq> tear_cols = {" << join(cols) << "};\n"
       << "  static constexpr std::array<int, num_blocks + 1> tear_sens_begin = {" << join(d_begin)
       << "};\n\n";
  }

 private:
  using BlockOuts = BlockRates;
  static constexpr const char* kIn = "    ";
  // The public functions take options of any real type; the blocks compute in T's.
  static constexpr const char* kOptions =
      "    [[maybe_unused]] const BasicBlockOptions<R> o = _options_as<R>(options);\n";
  int out(int k) const { return prog_.outputs[k]; }

  // q[c] (or qd, qdd) as the function being emitted names it: through the coordinate table in
  // a repeated block's function.
  std::string ref(const std::string& var, int c) const {
    return var + "[" + (local_.empty() ? idx(c) : "_i[" + idx(local_[c]) + "]") + "]";
  }
  // A repeated block's function prints the first block's coordinates (its comments' q[c] are
  // those of the first block; the code reads q[_i[k]]).
  std::string block_label(std::size_t bi) const {
    return "Block " + idx(local_.empty() ? static_cast<int>(bi) : first_block_) +
           (local_.empty() ? "" : " and the blocks alike");
  }
  std::string block_id(std::size_t bi) const {
    return local_.empty() ? idx(static_cast<int>(bi)) : "_b";
  }

  void emit_rolled_position(std::ostringstream& os, const std::string& name) {
    os << "  template <class T>\n"
       << "  static BlockReport<_real<T>> " << name << "_position(T* q, [[maybe_unused]] T t,\n"
       << "      [[maybe_unused]] const Params& p,\n"
       << "      [[maybe_unused]] const BasicBlockOptions<_real<T>>& o,\n"
       << "      BlockReport<_real<T>> report, [[maybe_unused]] T* trig,\n"
       << "      [[maybe_unused]] signed char* block_signs, const int* _i,\n"
       << "      [[maybe_unused]] const int* _s, [[maybe_unused]] int _b) noexcept {\n"
       << kIn << "using R [[maybe_unused]] = _real<T>;\n";
    if (!used_.empty()) os << kIn << "using " << used_ << ";\n";
    FunctionPrinter pr(prog_, symbols_);
    pr.read_through(&local_);
    position_body(os, pr, 0, 1);
    os << kIn << "return report;\n  }\n";
  }

  void emit_rolled_motion(std::ostringstream& os, const std::string& name, bool velocity,
                          bool acceleration) {
    os << "  template <class T>\n"
       << "  static BlockReport<_real<T>> " << name << "_" << motion_name(velocity, acceleration) << "("
       << motion_args(velocity, acceleration, true) << ",\n"
       << "      [[maybe_unused]] T* trig, const int* _i, [[maybe_unused]] const int* _s,\n"
       << "      [[maybe_unused]] int _b) noexcept {\n"
       << kIn << "using R [[maybe_unused]] = _real<T>;\n";
    if (!used_.empty()) os << kIn << "using " << used_ << ";\n";
    FunctionPrinter pr(prog_, symbols_);
    pr.read_through(&local_);
    motion_trig_ = true;
    motion_body(os, pr, velocity, acceleration, 0, 1, false);
    os << kIn << "return report;\n  }\n";
  }

  // A repeated block's call (its functions report failures with the block's index).
  void call_rolled(std::ostringstream& os, std::size_t bi, const std::string& function,
                   const std::string& args, bool slots) {
    const int g = roll_of_[bi], m = roll_member_[bi];
    const std::string name = "_roll" + idx(g);
    os << kIn << "report = " << name << "_" << function << "(" << args << ", " << name << "_i["
       << m << "], ";
    if (slots) os << (rolls_[g].slots[0].empty() ? "nullptr" : name + "_s[" + idx(m) + "]") << ", ";
    os << bi << ");\n" << kIn << "if (report.status != 0) return report;\n";
  }

  // The extra argument of every part when torn blocks are split: the sin and cos of their
  // rotated coordinates (2 per row of _torn_trig), owned by the public function.
  std::string sc_arg(bool declare) const {
    if (!torn_any_) return "";
    return declare ? ",\n      [[maybe_unused]] T* _sc" : ", _sc";
  }
  // The public function's _sc; with fill, their sin and cos at q (no cache: a solve of the rates
  // alone evaluates them, as the whole function does).
  void declare_sc(std::ostringstream& os, bool fill) {
    if (!torn_any_) return;
    os << kIn << "T _sc[" << std::max<std::size_t>(2, 2 * torn_trig_.size()) << "];\n";
    if (fill && !torn_trig_.empty())
      os << kIn << "for (int _k = 0; _k < " << torn_trig_.size() << "; ++_k)\n"
         << kIn << "  _trig(_sc[2 * _k], _sc[2 * _k + 1], q[_torn_trig[_k][0]], "
         << "static_cast<T*>(nullptr), 0);\n";
  }

  static std::string motion_name(bool velocity, bool acceleration) {
    return velocity && acceleration ? "solve_velocity_acceleration"
           : velocity               ? "solve_velocity"
                                    : "solve_acceleration";
  }
  // The arguments of a motion part: the public function's, then the report.
  static std::string motion_args(bool velocity, bool acceleration, bool declare) {
    const char* mu = "[[maybe_unused]] ";
    std::vector<std::string> a;
    const auto arg = [&](const std::string& type, const std::string& name) {
      a.push_back(declare ? mu + type + " " + name : name);
    };
    arg("const T*", "q");
    if (!velocity) arg("const T*", "qd");
    arg("T", "t");
    arg("const Params&", "p");
    if (velocity) arg("T*", "qd");
    if (acceleration) arg("T*", "qdd");
    arg("const BasicBlockOptions<_real<T>>&", "o");
    arg("BlockReport<_real<T>>", "report");
    std::string s;
    for (std::size_t k = 0; k < a.size(); ++k)
      s += (k == 0 ? "" : declare && k % 2 == 0 ? ",\n      " : ", ") + a[k];
    return s;
  }

  void call_parts(std::ostringstream& os, const std::string& name, const std::string& args) {
    for (std::size_t k = 0; k < ranges_.size(); ++k) {
      os << kIn << "report = " << name << k << "(" << args << ");\n";
      if (k + 1 < ranges_.size()) os << kIn << "if (report.status != 0) return report;\n";
    }
  }

  void part_header(std::ostringstream& os, const std::string& name, std::size_t k,
                   const std::string& params) {
    os << "  // Blocks " << ranges_[k].first << " to " << ranges_[k].second - 1 << " of "
       << name.substr(1) << ".\n"
       << "  template <class T>\n"
       << "  static BlockReport<_real<T>> " << name << "_part" << k << "(" << params << ") noexcept {\n"
       << kIn << "using R [[maybe_unused]] = _real<T>;\n";
    if (!used_.empty()) os << kIn << "using " << used_ << ";\n";
  }

  void emit_position_parts(std::ostringstream& os) {
    os << "\n private:\n";
    for (std::size_t k = 0; k < ranges_.size(); ++k) {
      part_header(os, "_solve_position", k,
                  "T* q, [[maybe_unused]] T t, [[maybe_unused]] const Params& p,\n"
                  "      [[maybe_unused]] const BasicBlockOptions<_real<T>>& o,\n"
                  "      BlockReport<_real<T>> report, [[maybe_unused]] T* trig,\n"
                  "      [[maybe_unused]] signed char* block_signs" +
                      sc_arg(true));
      FunctionPrinter pr(prog_, symbols_);
      position_body(os, pr, ranges_[k].first, ranges_[k].second);
      os << kIn << "return report;\n  }\n";
    }
    os << "\n public:\n";
  }

  void emit_motion_parts(std::ostringstream& os, bool velocity, bool acceleration) {
    os << "\n private:\n";
    for (std::size_t k = 0; k < ranges_.size(); ++k) {
      const bool save = parts_save(velocity, acceleration);
      part_header(os, "_" + motion_name(velocity, acceleration), k,
                  motion_args(velocity, acceleration, true) + ",\n      [[maybe_unused]] T* trig" +
                      sc_arg(true) + (save ? ", [[maybe_unused]] StepFactors<T>* factors" : ""));
      FunctionPrinter pr(prog_, symbols_);
      motion_trig_ = true;
      saving_ = save;
      motion_body(os, pr, velocity, acceleration, ranges_[k].first, ranges_[k].second, false);
      saving_ = false;
      motion_trig_ = false;
      os << kIn << "return report;\n  }\n";
    }
    os << "\n public:\n";
  }

  void prologue(std::ostringstream& os) {
    os << kIn << "using R = _real<T>;\n";
    if (!used_.empty()) os << kIn << "using " << used_ << ";\n";
    os << kOptions << kIn << "BlockReport<R> report;\n";
  }

  void finite_check(std::ostringstream& os, const char* v) {
    os << kIn << "if (!_all_finite<nq>(" << v << ")) return _fail(report, 3, -1);\n";
  }

  // Blocks [b0, b1).
  void position_body(std::ostringstream& os, FunctionPrinter& pr, int b0, int b1) {
    const std::string in = kIn;
    for (std::size_t bi = b0; bi < static_cast<std::size_t>(b1); ++bi) {
      const BlockPlan& plan = st_.plans[bi];
      const Block& b = plan.block;
      const int f = pos_first_[bi];
      const int k = static_cast<int>(b.rows.size());
      os << in << "// " << block_label(bi) << ": " << block_comment(b, to_string(plan.kind))
         << "\n";
      if (roll_of_[bi] >= 0) {
        call_rolled(os, bi, "position", "q, t, p, o, report, trig, block_signs", true);
        continue;
      }
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
      if (plan.kind == BlockKind::kExplicit) {
        if (lazy_trig_) declare_needed_trig(os, pr, outputs);
        pr.ensure(out(f), os, in);
        os << in << ref("q", b.cols[0]) << " = " << pr.text(out(f)) << ";\n";
        declare_trig(os, pr, b.cols[0], false);
        continue;
      }
      if (plan.kind == BlockKind::kExplicitGuarded) {
        if (lazy_trig_) declare_needed_trig(os, pr, outputs);
        pr.ensure(out(f), os, in);
        pr.ensure(out(f + 1), os, in);
        os << in << "{\n"
           << in << "  const T _c = " << pr.text(out(f)) << ";\n"
           << in << "  if (!(_mag(_c) > 0)) return _fail(report, _mag(_c) == 0 ? 2 : 3, " << block_id(bi)
           << ");\n"
           << in << "  " << ref("q", b.cols[0]) << " = -(" << pr.text(out(f + 1)) << ") / _c;\n"
           << in << "}\n";
        declare_trig(os, pr, b.cols[0], false);
        guarded_condition(os, pr, bi);
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
      const std::string bs = idx(static_cast<int>(bi));
      newton_declare(os, bi, b.cols);
      os << in << "R _st" << bs << " = 0;\n";
      os << in << "for (int _it = 1;; ++_it) {\n";
      pr.open_scope();
      const std::string in2 = in + "  ";
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
        os << in2 << "_step = std::max(_step, _mag(_r[" << i << "])"
           << inv_scale(c) << ");\n";
        step_criterion(os, in2, c, i);
      }
      os << in2 << "if (!_finite(_step)) return _fail(report, 3, " << block_id(bi) << ", _it);\n";
      linear_count(os, in2, bs, "_step");
      newton_stop(os, in2, bi, k, {"_st" + bs + " = _step;", "break;"});
      pr.close_scope();
      os << in << "}\n";
      std::vector<int> rows;
      for (int o = 0; o < k; ++o) rows.push_back(f + o);
      newton_finish(os, pr, bi, rows, "_st" + bs);
    }
  }

  // |output o| as an entry of Phi_q's column col, in the column's units (lengths times their
  // coordinate scale), for the condition checks.
  std::string scaled_entry(FunctionPrinter& pr, int col, int o) {
    return "_mag(" + pr.text(out(o)) + ")" +
           (length_coordinate(col) ? " * R(" + ref("coordinate_scales", col) + ")" : "");
  }

  // A guarded block's coefficient against its row's couplings to earlier blocks, at the solved
  // q: the block's condition within all of Phi_q (a coefficient that is small beside them is a
  // near-singular Phi_q although it is not zero). Recorded in the report's rcond.
  void guarded_condition(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi) {
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
       << kIn << "  if (!(_rc > o.min_rcond)) return _fail(report, 2, " << b << ");\n"
       << kIn << "  report.rcond = std::min(report.rcond, _rc);\n"
       << kIn << "}\n";
  }

  // Newton blocks check what the dense path checks (kernels/newton.hpp): before the loop, the
  // state its last iteration leaves for the recheck: the row scales (_rmax), the columns'
  // scales (_d: lengths times length_scale), the scaled |q| sum, the condition estimate and
  // the determinant's sign of the last factorization, the iteration count and whether the step
  // criterion held.
  void newton_declare(std::ostringstream& os, std::size_t bi, const std::vector<int>& cols) {
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

  // Whether a coordinate is a length (scaled by length_scale) rather than an angle.
  // Lengths (and scalars) are measured in units of their coordinate_scales entry, angles in
  // radians: the factor that does it in steps and roundings ("" for an angle), and the scale.
  bool length_coordinate(int c) const { return kinds_[c] != CoordinateKind::kAngle; }
  std::string inv_scale(int c) const {
    return length_coordinate(c) ? " * R(1 / " + ref("coordinate_scales", c) + ")" : "";
  }

  // The step criterion for block coordinate c (the update in _r[i]), with the rounding
  // allowance; adds its scaled |q| to _qs.
  void step_criterion(std::ostringstream& os, const std::string& in, int c, int i) {
    const std::string scale = inv_scale(c);
    os << in << "_qs += _mag(" << ref("q", c) << ")" << scale << ";\n"
       << in << "_small &= _step_converged(_mag(_r[" << i << "])" << scale << ", _mag("
       << ref("q", c) << ")" << scale << ", o.tolerance);\n";
  }

  // Counts the linear steps (the Newton policy's convergence-rate test) in _nl<b>.
  void linear_count(std::ostringstream& os, const std::string& in, const std::string& b,
                    const std::string& step) {
    os << in << "_nl" << b << " += _linear_step(" << step << ", _pv" << b << ");\n"
       << in << "_pv" << b << " = " << step << ";\n";
  }

  // The end of an iteration: stop when the step criterion holds (or the fixed budget is
  // spent), or at max_iterations; then keep what the recheck needs (`keep`: more of it).
  void newton_stop(std::ostringstream& os, const std::string& in, std::size_t bi, int k,
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
  void newton_finish(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
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
       << ", o, " << step << ", _nl" << b << ", _res" << b << ", _qs" << b << ", _rc" << b
       << ", _sg" << b << ", block_signs))\n"
       << kIn << "  return report;\n";
  }

  // One Newton update inside an iteration: _r[] holds the residuals of a k x k system whose
  // matrix is `a` (row-major texts); leaves the step in _r, or reports a singular block.
  void newton_solve(std::ostringstream& os, const std::string& in, std::size_t bi, int k,
                    const std::vector<std::string>& a) {
    const std::string b = idx(static_cast<int>(bi));
    if (k == 1) {
      os << in << "const T _a = " << a[0] << ";\n"
         << in << "if (!(_mag(_a) > 0)) return _fail(report, _mag(_a) == 0 ? 2 : 3, " << block_id(bi)
         << ", _it);\n"
         << in << "_rmax" << b << "[0] = _mag(_a) * _cs" << b << "[0];\n"
         << in << "_r[0] /= _a;\n";
      return;
    }
    os << in << "T _a[" << k * k << "] = {" << join(a) << "};\n"
       << in << "_row_max<" << k << ">(_a, _cs" << b << ", _rmax" << b << ");\n"
       << in << "int _piv[" << k << "];\n"
       << in << "const R _ratio = _lu_factor<" << k << ">(_a, _piv);\n"
       << in << "if (!(_ratio > o.singular_pivot_ratio))\n"
       << in << "  return _fail(report, _ratio == _ratio ? 2 : 3, " << block_id(bi) << ", _it);\n"
       << in << "_lu_solve<" << k << ">(_a, _piv, _r);\n";
  }

  // Block bi's k x k matrix `a` for the rates, kept as _a<bi> (k = 1: the divisor) or factored
  // into _a<bi>/_piv<bi>; reports a singular block.
  void factor(std::ostringstream& os, std::size_t bi, int k, const std::vector<std::string>& a) {
    const std::string in = kIn, b = idx(static_cast<int>(bi));
    if (k == 1) {
      os << in << "const T _a" << b << " = " << a[0] << ";\n"
         << in << "if (!(_mag(_a" << b << ") > 0)) return _fail(report, _mag(_a" << b
         << ") == 0 ? 2 : 3, " << block_id(bi) << ");\n";
      save_factors(os, bi, k);
      return;
    }
    os << in << "T _a" << b << "[" << k * k << "] = {" << join(a) << "};\n"
       << in << "int _piv" << b << "[" << k << "];\n"
       << in << "const R _ratio" << b << " = _lu_factor<" << k << ">(_a" << b << ", _piv"
       << b << ");\n"
       << in << "if (!(_ratio" << b << " > o.singular_pivot_ratio))\n"
       << in << "  return _fail(report, _ratio" << b << " == _ratio" << b << " ? 2 : 3, " << block_id(bi)
       << ");\n";
    save_factors(os, bi, k);
  }

  // In solve_step: block bi's k x k factors (and a torn block's tear sensitivities, _D) into
  // StepFactors.
  void save_factors(std::ostringstream& os, std::size_t bi, int k) {
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
      const SensitivityName d_name = torn_split(bi) ? sensitivity_array(bi, "_D" + b)
                                                    : sensitivity_locals(bi, "_D" + b + "_");
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
  // Whether solve_step keeps block bi's factors: a K x K or torn block solved in solve_step
  // or its parts, not in a repeated block's function (1 x 1 blocks need none: their
  // coefficient is an entry of Phi_q).
  bool kept_factors(std::size_t bi) const {
    const BlockPlan& plan = st_.plans[bi];
    return step_factors_ && roll_of_[bi] < 0 && (plan.torn() || plan.block.rows.size() > 1);
  }
  // A torn block's rows (or coordinates) in its rate solve's order: the assigned ones, then
  // the residual rows (the tears); another block's as in the structure tables.
  std::vector<int> torn_order(std::size_t bi, bool rows) const {
    const BlockPlan& plan = st_.plans[bi];
    if (!plan.torn()) return rows ? plan.block.rows : plan.block.cols;
    std::vector<int> v;
    for (const auto& [r, c] : plan.assigned) v.push_back(rows ? r : c);
    for (int x : rows ? plan.residuals : plan.tears) v.push_back(x);
    return v;
  }
  // The parts of a split solve_velocity_acceleration keep the factors too (solve_step calls
  // them with its StepFactors).
  bool parts_save(bool velocity, bool acceleration) const {
    return step_factors_ && velocity && acceleration;
  }
  void factors_rcond(std::ostringstream& os, const char* value) {
    if (step_factors_) os << kIn << "if (factors) factors->rcond = " << value << ";\n";
  }

  // sin and cos of the block's angles: evaluated once at the start, then rotated by each
  // Newton update (_rotate), and left in scope for the terms after the loop.
  std::vector<int> declare_rotations(std::ostringstream& os, FunctionPrinter& pr,
                                     const Block& b) {
    std::vector<int> rotated;
    for (int c : b.cols)
      if (declare_trig(os, pr, c, true)) rotated.push_back(c);
    return rotated;
  }

  // `T _sinC, _cosC` for a coordinate whose sin or cos the program uses, from the cache (see
  // _trig); later terms read them. Explicit coordinates (always = false) only when the function
  // being emitted needs them. Returns whether they were declared.
  bool declare_trig(std::ostringstream& os, FunctionPrinter& pr, int c, bool always) {
    if (trig_slot_[c] < 0) return false;
    const auto needed = [&](int id) { return id >= 0 && (step_mode_ || in_position_[id]); };
    if (!always && !needed(sin_of_[c]) && !needed(cos_of_[c])) return false;
    const std::string s = "_sin" + idx(c), co = "_cos" + idx(c);
    os << kIn << "T " << s << ", " << co << ";\n"
       << kIn << "_trig(" << s << ", " << co << ", " << ref("q", c) << ", trig, "
       << (local_.empty() ? idx(trig_slot_[c]) : "_s[" + idx(trig_slot_[c]) + "]") << ");\n";
    if (sin_of_[c] >= 0) pr.bind(sin_of_[c], s);
    if (cos_of_[c] >= 0) pr.bind(cos_of_[c], co);
    return true;
  }

  // In a function that has the trig cache (motion_trig_): sin and cos, from the cache, of the
  // coordinates block bi's rates read that are not yet in scope.
  void declare_motion_trig(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                           bool velocity, bool acceleration) {
    const BlockOuts& bo = blocks_[bi];
    std::vector<int> outputs = bo.jbb;
    for (const auto& [rc, o] : bo.tjac) outputs.push_back(o);
    for (const auto& row : bo.coupling)
      for (const auto& [c, o] : row) outputs.push_back(o);
    if (velocity) outputs.insert(outputs.end(), bo.nu.begin(), bo.nu.end());
    if (acceleration) outputs.insert(outputs.end(), bo.gamma.begin(), bo.gamma.end());
    declare_needed_trig(os, pr, outputs);
  }

  // sin and cos, from the cache, of the coordinates that `outputs` read through sin or cos and
  // whose values are not yet in scope (a repeated block's coordinates, or an earlier part's).
  void declare_needed_trig(std::ostringstream& os, FunctionPrinter& pr,
                           const std::vector<int>& outputs) {
    std::vector<int> nodes;
    for (int o : outputs) nodes.push_back(out(o));
    for (int c : trig_read(pr, nodes)) declare_trig(os, pr, c, true);
  }
  // The coordinates whose sin or cos the trees of `nodes` read and that are not yet in scope.
  std::set<int> trig_read(FunctionPrinter& pr, const std::vector<int>& nodes) const {
    std::vector<int> stack = nodes;
    std::set<int> seen, coords;
    while (!stack.empty()) {
      const int id = stack.back();
      stack.pop_back();
      if (id == Program::kZero || pr.named(id) || !seen.insert(id).second) continue;
      const Node& n = prog_.nodes[id];
      if (n.kind == OpKind::kSin || n.kind == OpKind::kCos) {
        const Node& a = prog_.nodes[n.args[0]];
        if (a.kind == OpKind::kInput && a.input.kind == InputKind::kQ) {
          coords.insert(a.input.index);
          continue;
        }
      }
      for (int a : n.args) stack.push_back(a);
    }
    return coords;
  }

  // In a split torn block's functions: `T& _sinC = _sc[..]` (and _cosC) for its coordinates
  // that `nodes` read or that are `updated`, then sin and cos from the cache of the other
  // coordinates `nodes` read.
  void torn_trig(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                 const std::vector<int>& nodes, const std::vector<int>& updated) {
    const TornParts& tp = torn_parts_[bi];
    std::set<int> coords = trig_read(pr, nodes);
    coords.insert(updated.begin(), updated.end());
    for (std::size_t i = 0; i < tp.rotated.size(); ++i) {
      const int c = tp.rotated[i];
      if (!coords.count(c)) continue;
      const int k = 2 * (tp.trig_first + static_cast<int>(i));
      os << kIn << "[[maybe_unused]] T& _sin" << c << " = _sc[" << k << "];\n"
         << kIn << "[[maybe_unused]] T& _cos" << c << " = _sc[" << k + 1 << "];\n";
      if (sin_of_[c] >= 0) pr.bind(sin_of_[c], "_sin" + idx(c));
      if (cos_of_[c] >= 0) pr.bind(cos_of_[c], "_cos" + idx(c));
    }
    for (int c : trig_read(pr, nodes)) declare_trig(os, pr, c, true);
  }

  // A split torn block's own code (its Newton loop, or its rates): sin and cos (in the
  // position first evaluated into _sc from the cache), and the terms of its residual rows that
  // do not read its coordinates.
  void torn_host_trig(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi, bool position) {
    const TornParts& tp = torn_parts_[bi];
    if (position && !tp.rotated.empty())
      os << kIn << "for (int _k = " << tp.trig_first << "; _k < "
         << tp.trig_first + static_cast<int>(tp.rotated.size()) << "; ++_k)\n"
         << kIn << "  _trig(_sc[2 * _k], _sc[2 * _k + 1], q[_torn_trig[_k][0]], trig, "
         << "_torn_trig[_k][1]);\n";
    const std::vector<int> host = torn_host_outputs(bi, position, !position);
    torn_trig(os, pr, bi, host, st_.plans[bi].tears);
    if (position)
      for (int id : host)
        pr.ensure(id, os, kIn, [&](int n) { return level_[n] < static_cast<int>(bi); });
  }

  // The private functions of the split torn blocks (split_blocks), called in order from the
  // blocks' Newton loops and rates: each takes a run of the assigned coordinates.
  void emit_torn_parts(std::ostringstream& os, bool velocity, bool acceleration) {
    if (!torn_any_) return;
    os << "\n private:\n";
    if (!torn_trig_.empty()) {
      os << "  // Split torn blocks' coordinates with rotated sin and cos: {q index, trig slot};\n"
         << "  // the values live in _sc, 2 per row.\n";
      emit_table(os, "_torn_trig", torn_trig_);
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

  // The parameters every part of a split torn block takes after its first.
  static constexpr const char* kTornPartParams =
      "[[maybe_unused]] T t, [[maybe_unused]] const Params& p,\n"
      "      [[maybe_unused]] T* trig, [[maybe_unused]] T* _sc";

  // One part function of torn block bi: `_torn<b>_<kind>_part<k>(params)`, its body printed by
  // `body` over the assigned coordinates `range`.
  void emit_torn_part(std::ostringstream& os, std::size_t bi, const std::string& kind,
                      std::size_t k, const std::pair<int, int>& range, const std::string& what,
                      const std::string& params,
                      const std::function<void(FunctionPrinter&)>& body) {
    os << "  // Block " << idx(static_cast<int>(bi)) << ", assigned coordinates " << range.first
       << " to " << range.second - 1 << ": " << what << ".\n"
       << "  template <class T>\n"
       << "  static void _torn" << idx(static_cast<int>(bi)) << "_" << kind << "_part" << k << "("
       << params << ") noexcept {\n";
    if (!used_.empty()) os << kIn << "using " << used_ << ";\n";
    FunctionPrinter pr(prog_, symbols_);
    body(pr);
    os << "  }\n";
  }

  // Part k of torn block bi's position: its assigned coordinates' values, then (when asked)
  // their sensitivities to the tears, for the Newton loop's Schur complement.
  void emit_torn_position_part(std::ostringstream& os, std::size_t bi, std::size_t k) {
    const TornParts& tp = torn_parts_[bi];
    const BlockPlan& plan = st_.plans[bi];
    const int f = pos_first_[bi];
    const std::string in = kIn;
    const auto [a0, a1] = tp.position[k];
    emit_torn_part(
        os, bi, "position", k, tp.position[k], "their values, then their sensitivities (_d)",
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
          sensitivities(os, pr, bi, pos_tjac_[bi], tp.dependency, in, sensitivity_array(bi, "_d"),
                        "", a0, a1);
        });
  }

  // Part k of torn block bi's rates: the sensitivities to the tears (_D), the correction
  // x += _D x_tears, and qd and qdd with the tears' at zero.
  void emit_torn_rate_parts(std::ostringstream& os, std::size_t bi, std::size_t k, bool velocity,
                            bool acceleration) {
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

  // q[c] = value, keeping the rotated sin and cos of q[c] current.
  void update(std::ostringstream& os, const std::string& in, const std::vector<int>& rotated, int c,
              const std::string& value) {
    const bool rotate = std::find(rotated.begin(), rotated.end(), c) != rotated.end();
    const std::string q = ref("q", c);
    if (rotate) os << in << "const T _old" << c << " = " << q << ";\n";
    os << in << q << " = " << value << ";\n";
    if (rotate)
      os << in << "_rotate(_sin" << c << ", _cos" << c << ", " << q << " - _old" << c << ", " << q
         << ");\n";
  }

  // Appends `coefficient * x` (a Phi_q output) to a sum's text, folding +-1; x empty: the
  // coefficient alone.
  void add_product(std::string& sum, FunctionPrinter& pr, int output, const std::string& x) {
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
  std::string divide_negated(FunctionPrinter& pr, const std::string& sum, int output,
                             bool negate) {
    const Node& n = prog_.nodes[out(output)];
    if (sum.empty()) return "T(0)";
    const bool one = n.kind == OpKind::kConst && (n.value == 1 || n.value == -1);
    const bool minus = negate != (one && n.value == -1);
    const std::string body = minus ? "-(" + sum + ")" : "(" + sum + ")";
    return one ? body : body + " / " + pr.atom_text(out(output));
  }

  std::map<int, std::vector<char>> tear_dependency(std::size_t bi) const {
    return plan_.tear_dependency(bi);
  }
  bool torn_split(std::size_t bi) const { return plan_.torn_split(bi); }
  std::vector<int> torn_host_outputs(std::size_t bi, bool position, bool rates) const {
    return plan_.torn_host_outputs(bi, position, rates);
  }

  // The name of dq[c]/dq[tear j] (c = plan.assigned[a].second) in the function being emitted.
  using SensitivityName = std::function<std::string(std::size_t j, int a)>;
  // Locals `prefix<j>_<c>` (a whole block), or a caller-owned array (a split torn block).
  SensitivityName sensitivity_locals(std::size_t bi, const std::string& prefix) const {
    return [this, bi, prefix](std::size_t j, int a) {
      return prefix + std::to_string(j) + "_" + idx(st_.plans[bi].assigned[a].second);
    };
  }
  SensitivityName sensitivity_array(std::size_t bi, const std::string& array) const {
    const int n = static_cast<int>(st_.plans[bi].assigned.size());
    return [n, array](std::size_t j, int a) {
      return array + "[" + std::to_string(static_cast<int>(j) * n + a) + "]";
    };
  }

  // The sum over row r's block coordinates (but `skip`) of Phi_q * dq/dtear_j.
  std::string row_sum(FunctionPrinter& pr, std::size_t bi,
                      const std::map<std::pair<int, int>, int>& entries,
                      const std::map<int, std::vector<char>>& dep, const SensitivityName& d_name,
                      const std::map<int, int>& assigned_index, int r, int skip, std::size_t j) {
    const BlockPlan& plan = st_.plans[bi];
    std::string sum;
    for (const auto& [rc, o] : row_entries(entries, r)) {
      if (rc.second == skip || !dep.at(rc.second)[j]) continue;
      add_product(sum, pr, o,
                  rc.second == plan.tears[j] ? "" : d_name(j, assigned_index.at(rc.second)));
    }
    return sum;
  }
  std::map<int, int> assigned_index(std::size_t bi) const {
    std::map<int, int> index;
    const auto& assigned = st_.plans[bi].assigned;
    for (std::size_t a = 0; a < assigned.size(); ++a)
      index[assigned[a].second] = static_cast<int>(a);
    return index;
  }

  // Sensitivities of the assigned coordinates plan.assigned[a0..a1) to the tears (dq[c]/dq[tear
  // j], from the assigned rows in order: the rows stay satisfied), `declare` name = ...;.
  void sensitivities(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                     const std::map<std::pair<int, int>, int>& entries,
                     const std::map<int, std::vector<char>>& dep, const std::string& in,
                     const SensitivityName& d_name, const char* declare, int a0, int a1) {
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
  std::vector<std::string> schur_matrix(FunctionPrinter& pr, std::size_t bi,
                                        const std::map<std::pair<int, int>, int>& entries,
                                        const std::map<int, std::vector<char>>& dep,
                                        const SensitivityName& d_name) {
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
  std::vector<std::string> schur(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
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
  void torn_position(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
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
    os << in2 << "if (!_finite(_step" << b << ")) return _fail(report, 3, " << block_id(bi) << ", _it);\n";
    linear_count(os, in2, b, "_step" + b);
    newton_stop(os, in2, bi, m, {"_stop" + b + " = true;"});
    pr.close_scope();
    os << in << "}\n";
    std::vector<int> rows;
    for (int i = 0; i < m; ++i) rows.push_back(f + n_assigned + i);
    newton_finish(os, pr, bi, rows, "_step" + b);
  }

  // Blocks [b0, b1); checks: end with the finite checks of qd and qdd.
  void motion_body(std::ostringstream& os, FunctionPrinter& pr, bool velocity, bool acceleration,
                   int b0, int b1, bool checks) {
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
      os << in << "// " << block_label(bi) << ": " << block_comment(st_.plans[bi].block, "")
         << "\n";
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

  void solve_rows(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
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
    for (int i = 0; i < k; ++i)
      os << in << "  " << ref(var, blk.cols[i]) << " = _x[" << i << "];\n";
    os << in << "}\n";
  }

  // Row i of block bi's rates: rhs minus its couplings to earlier blocks' `var`.
  std::string rate_rhs(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
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

  // A torn block's row r: `rhs` minus the row's non-tear block entries times x (other than
  // `skip`).
  std::string reduced_rhs(FunctionPrinter& pr, std::size_t bi, const std::string& rhs, int r,
                          int skip, const char* var) {
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
  void solve_tears(std::ostringstream& os, std::size_t bi, const std::vector<std::string>& g,
                   const char* var) {
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
  void correct(std::ostringstream& os, std::size_t bi, const std::map<int, std::vector<char>>& dep,
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
  void solve_torn_rows_split(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                             const std::vector<int>& rhs, const char* var) {
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
  void solve_torn_rows(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
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

  // The plan printed (structure stage), and names for its parts.
  const SolverPlan& plan_;
  const SymbolTable& symbols_;
  std::vector<CoordinateKind> kinds_;  // per coordinate
  const Structure& st_ = plan_.structure;
  const std::vector<GiNaC::ex>& outs_ = plan_.program.exprs;  // the outputs before lowering
  const Program& prog_ = plan_.program.program;
  // The std functions the program calls, for each function's `using std::sin, ...;`.
  const std::string used_ = std_functions(prog_);
  const std::vector<int>& pos_first_ = plan_.program.position_first;
  const int pos_end_ = plan_.program.position_end;
  const std::vector<std::map<std::pair<int, int>, int>>& pos_tjac_ = plan_.program.torn_jacobian;
  const std::vector<BlockOuts>& blocks_ = plan_.program.rates;
  const std::vector<int>& level_ = plan_.program.level;
  // Per coordinate: its named sin / cos node, or -1; its slot in the trig cache, or -1.
  const std::vector<int>&sin_of_ = plan_.program.sin_of, &cos_of_ = plan_.program.cos_of;
  const std::vector<int>& trig_slot_ = plan_.program.trig_slot;
  const int trig_slots_ = plan_.program.trig_slots;
  const std::vector<char>& in_position_ = plan_.program.in_position;  // per node
  const std::vector<RepeatedBlocks>& rolls_ = plan_.repeated;
  // Per block: its class of repeated blocks and its row there, or -1.
  const std::vector<int>&roll_of_ = plan_.class_of, &roll_member_ = plan_.member_of;
  const PartRanges& ranges_ = plan_.ranges;  // the parts' blocks; empty: one function
  const std::vector<TornParts>& torn_parts_ = plan_.torn_parts;  // per block
  const std::vector<std::vector<int>>& torn_trig_ = plan_.torn_trig;  // {coordinate, slot}
  const bool torn_any_ = plan_.torn_any;  // some torn block is split
  std::vector<int> local_;            // a repeated block's function: coordinate -> table slot
  int first_block_ = -1;              // a repeated block's function: the first block alike
  bool step_mode_ = false;            // emitting solve_step (motion terms follow position)
  bool motion_trig_ = false;          // the motion being emitted has the trig cache
  bool step_factors_ = false;         // solve_step takes StepFactors (the header has forces)
  bool saving_ = false;               // emitting solve_step's rates: keep the factors
  // sin and cos of a coordinate are declared where first read (not where it is solved): with
  // repeated blocks, whose functions solve coordinates the caller reads.
  bool lazy_trig_ = false;
  std::vector<std::string> divisor_;
};

BlockSolverPrinter::BlockSolverPrinter(const SymbolicModel& model, const SymbolTable& symbols,
                                       const SolverPlan& plan)
    : impl_(std::make_unique<BlockEmitter>(model.coordinate_kinds, symbols, plan)) {}
BlockSolverPrinter::~BlockSolverPrinter() = default;
int BlockSolverPrinter::trig_cache_size() const { return impl_->trig_cache_size(); }
void BlockSolverPrinter::keep_step_factors() { impl_->keep_step_factors(); }
void BlockSolverPrinter::emit_step_factors(std::ostringstream& os) const {
  impl_->emit_step_factors(os);
}
void BlockSolverPrinter::emit_position(std::ostringstream& os) { impl_->emit_position(os); }
void BlockSolverPrinter::emit_motion(std::ostringstream& os, bool velocity, bool acceleration) {
  impl_->emit_motion(os, velocity, acceleration);
}
void BlockSolverPrinter::emit_step(std::ostringstream& os) { impl_->emit_step(os); }
void BlockSolverPrinter::emit_rolls(std::ostringstream& os, bool velocity, bool acceleration) {
  impl_->emit_rolls(os, velocity, acceleration);
}

}  // namespace kinegen::codegen::emit_detail
