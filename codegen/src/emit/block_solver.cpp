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

#include "block_emitter.hpp"
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

// The functions of the repeated blocks and their coordinate tables (private members).
void BlockEmitter::emit_rolls(std::ostringstream& os, bool velocity, bool acceleration) {
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

void BlockEmitter::emit_position(std::ostringstream& os) {
  os << "  // Position: each block in turn, explicit or by Newton on the block alone; q holds\n"
     << "  // the start (the previous solution or a prediction) and receives the solution.\n"
     << "  // trig: optional cache of trig_cache_size values, kept by the caller from call to "
        "call\n"
     << "  // (fill it with NaN first), so that sin and cos near the last values are rotations.\n"
     << "  // block_signs: optional, num_blocks entries kept by the caller (zero first): each "
        "Newton\n"
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
    call_parts(os, "_solve_position_part", "q, t, p, o, report, trig, block_signs" + sc_arg(false));
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

void BlockEmitter::emit_motion(std::ostringstream& os, bool velocity, bool acceleration) {
  if (velocity && acceleration) {
    os << "  // Velocity (Phi_q qd = nu) and acceleration (Phi_q qdd = gamma) at a solved q,\n"
       << "  // block by block with one factorization per block.\n"
       << "  template <class T, class U>\n"
       << "  static BlockReport<_real<T>> solve_velocity_acceleration([[maybe_unused]] const T* "
          "q,\n"
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
    call_parts(
        os, "_" + name + "_part",
        motion_args(velocity, acceleration, false) + ", static_cast<T*>(nullptr)" + sc_arg(false) +
            (parts_save(velocity, acceleration) ? ", static_cast<StepFactors<T>*>(nullptr)" : ""));
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
void BlockEmitter::emit_step(std::ostringstream& os) {
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
    call_parts(os, "_solve_position_part", "q, t, p, o, report, trig, block_signs" + sc_arg(false));
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

// StepFactors and the tables _block_transposed_reusing reads (kernels/block_linear.hpp):
// where each block's factors are, whether solve_step keeps them (not in a repeated block's
// function), and each torn block's rows and coordinates in the
// order of its rate solve (assigned, then residual rows and tears).
void BlockEmitter::emit_step_factors(std::ostringstream& os) const {
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

void BlockEmitter::emit_rolled_position(std::ostringstream& os, const std::string& name) {
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

void BlockEmitter::emit_rolled_motion(std::ostringstream& os, const std::string& name,
                                      bool velocity, bool acceleration) {
  os << "  template <class T>\n"
     << "  static BlockReport<_real<T>> " << name << "_" << motion_name(velocity, acceleration)
     << "(" << motion_args(velocity, acceleration, true) << ",\n"
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
void BlockEmitter::call_rolled(std::ostringstream& os, std::size_t bi, const std::string& function,
                               const std::string& args, bool slots) {
  const int g = roll_of_[bi], m = roll_member_[bi];
  const std::string name = "_roll" + idx(g);
  os << kIn << "report = " << name << "_" << function << "(" << args << ", " << name << "_i[" << m
     << "], ";
  if (slots) os << (rolls_[g].slots[0].empty() ? "nullptr" : name + "_s[" + idx(m) + "]") << ", ";
  os << bi << ");\n" << kIn << "if (report.status != 0) return report;\n";
}

// The public function's _sc; with fill, their sin and cos at q (no cache: a solve of the rates
// alone evaluates them, as the whole function does).
void BlockEmitter::declare_sc(std::ostringstream& os, bool fill) {
  if (!uses_sc()) return;
  os << kIn << "T _sc[" << std::max<std::size_t>(2, 2 * (torn_trig_.size() + split_trig_.size()))
     << "];\n";
  if (fill && !torn_trig_.empty())
    os << kIn << "for (int _k = 0; _k < " << torn_trig_.size() << "; ++_k)\n"
       << kIn << "  _trig(_sc[2 * _k], _sc[2 * _k + 1], q[_torn_trig[_k][0]], "
       << "static_cast<T*>(nullptr), 0);\n";
  if (fill && !split_trig_.empty()) {
    const std::string at =
        torn_trig_.empty() ? "2 * _k" : idx(2 * static_cast<int>(torn_trig_.size())) + " + 2 * _k";
    os << kIn << "for (int _k = 0; _k < " << split_trig_.size() << "; ++_k)\n"
       << kIn << "  _trig(_sc[" << at << "], _sc[" << at << " + 1], q[_split_trig[_k][0]], "
       << "static_cast<T*>(nullptr), 0);\n";
  }
}

void BlockEmitter::index_sc() {
  const int nq = static_cast<int>(trig_slot_.size());
  sc_index_.assign(nq, -1);
  for (std::size_t bi = 0; bi < torn_parts_.size(); ++bi) {
    const TornParts& tp = torn_parts_[bi];
    for (std::size_t i = 0; i < tp.rotated.size(); ++i)
      sc_index_[tp.rotated[i]] = 2 * (tp.trig_first + static_cast<int>(i));
  }
  if (ranges_.empty() || !rolls_.empty()) return;
  split_sc_ = true;
  for (int c = 0; c < nq; ++c) {
    if (trig_slot_[c] < 0 || sc_index_[c] >= 0) continue;
    sc_index_[c] = 2 * static_cast<int>(torn_trig_.size() + split_trig_.size());
    split_trig_.push_back({c, trig_slot_[c]});
  }
}

// The arguments of a motion part: the public function's, then the report.
std::string BlockEmitter::motion_args(bool velocity, bool acceleration, bool declare) {
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

void BlockEmitter::call_parts(std::ostringstream& os, const std::string& name,
                              const std::string& args) {
  for (std::size_t k = 0; k < ranges_.size(); ++k) {
    os << kIn << "report = " << name << k << "(" << args << ");\n";
    if (k + 1 < ranges_.size()) os << kIn << "if (report.status != 0) return report;\n";
  }
}

void BlockEmitter::part_header(std::ostringstream& os, const std::string& name, std::size_t k,
                               const std::string& params) {
  os << "  // Blocks " << ranges_[k].first << " to " << ranges_[k].second - 1 << " of "
     << name.substr(1) << ".\n"
     << "  template <class T>\n"
     << "  static BlockReport<_real<T>> " << name << "_part" << k << "(" << params
     << ") noexcept {\n"
     << kIn << "using R [[maybe_unused]] = _real<T>;\n";
  if (!used_.empty()) os << kIn << "using " << used_ << ";\n";
}

void BlockEmitter::emit_position_parts(std::ostringstream& os) {
  os << "\n private:\n";
  sc_ready_.assign(trig_slot_.size(), 0);
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
  sc_in_position_ = sc_ready_;
  os << "\n public:\n";
}

void BlockEmitter::emit_motion_parts(std::ostringstream& os, bool velocity, bool acceleration) {
  os << "\n private:\n";
  // The rates start from what the position left in _sc (the whole function's variables).
  sc_ready_ = sc_in_position_;
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

BlockSolverPrinter::BlockSolverPrinter(const SymbolicModel& model, const SymbolTable& symbols,
                                       const SolverPlan& plan)
    : impl_(std::make_unique<BlockEmitter>(model.coordinate_kinds, symbols, plan)) {}
BlockSolverPrinter::~BlockSolverPrinter() = default;
int BlockSolverPrinter::trig_cache_size() const { return impl_->trig_cache_size(); }
void BlockSolverPrinter::keep_step_factors() { impl_->keep_step_factors(); }
void BlockSolverPrinter::check_branches() { impl_->check_branches(); }
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
