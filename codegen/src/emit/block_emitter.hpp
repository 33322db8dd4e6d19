// The emit stage's BlockEmitter, behind BlockSolverPrinter (block_solver.hpp): one class whose
// members print the block functions, defined by concern in block_solver.cpp (the public
// functions, their parts and the repeated blocks' functions), block_position.cpp (explicit,
// guarded and Newton blocks), block_trig.cpp (sin and cos: the cache, rotations, _sc),
// block_rates.cpp (velocity and acceleration, the factors solve_step keeps) and block_torn.cpp
// (torn blocks: Newton on the tears, the Schur complement, the split parts).
// Private to the emit stage.
#pragma once

#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "kinegen/codegen/structure/block_program.hpp"
#include "kinegen/codegen/structure/solver_plan.hpp"
#include "kinegen/codegen/structure/structure.hpp"
#include "printer.hpp"

namespace kinegen::codegen::emit_detail {

// "rows 0, 1 -> q[2], q[5] (kind)": a block's comment.
std::string block_comment(const Block& b, const char* kind);

// Where StepFactors keeps each block's factors (offsets, in block order, with one past the
// end): a K x K block's LU in a (none for 1 x 1), a torn block's m x m Schur complement there
// and its assigned coordinates' sensitivities to the tears (assigned x m, row-major) in d; the
// pivots at the block's first place in block_cols.
struct FactorLayout {
  std::vector<int> a_begin{0}, d_begin{0}, piv_begin{0};
};
FactorLayout factor_layout(const Structure& st);

// Position, velocity and acceleration block by block. One program holds every expression the
// block functions need, so each function shares terms (sin and cos of an angle are computed
// once per function) and the full-step function shares them between the phases. Terms are
// printed where first needed; those inside a Newton loop go out of scope with it.
class BlockEmitter {
 public:
  BlockEmitter(const std::vector<CoordinateKind>& kinds, const SymbolTable& symbols,
               const SolverPlan& plan)
      : plan_(plan), symbols_(symbols), kinds_(kinds), lazy_trig_(!plan.repeated.empty()) {
    index_sc();
  }
  int trig_cache_size() const { return 3 * trig_slots_; }
  // The functions of the repeated blocks and their coordinate tables (private members).
  void emit_rolls(std::ostringstream& os, bool velocity, bool acceleration);
  void emit_position(std::ostringstream& os);
  void emit_motion(std::ostringstream& os, bool velocity, bool acceleration);
  // The full step: position, then velocity and acceleration, sharing every term.
  void emit_step(std::ostringstream& os);
  // solve_step keeps its factors for solve_forces (StepFactors, emit_step_factors).
  void keep_step_factors() { step_factors_ = true; }
  // solve_position and solve_step check the branch conditions (_branches_hold) at the solved q.
  void check_branches() { branches_ = true; }
  // StepFactors and the tables _block_transposed_reusing reads (kernels/block_linear.hpp):
  // where each block's factors are, whether solve_step keeps them (not in a repeated block's
  // function), and each torn block's rows and coordinates in the
  // order of its rate solve (assigned, then residual rows and tears).
  void emit_step_factors(std::ostringstream& os) const;

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
  void emit_rolled_position(std::ostringstream& os, const std::string& name);
  void emit_rolled_motion(std::ostringstream& os, const std::string& name, bool velocity,
                          bool acceleration);
  // A repeated block's call (its functions report failures with the block's index).
  void call_rolled(std::ostringstream& os, std::size_t bi, const std::string& function,
                   const std::string& args, bool slots);
  // The extra argument of every part when torn blocks are split: the sin and cos of their
  // rotated coordinates (2 per row of _torn_trig), owned by the public function.
  std::string sc_arg(bool declare) const {
    if (!uses_sc()) return "";
    return declare ? ",\n      [[maybe_unused]] T* _sc" : ", _sc";
  }
  // Whether the functions pass _sc: some torn block is split, or the solver is split into
  // parts (without repeated blocks), whose sin and cos pass between the parts in _sc as the
  // whole function keeps them in its variables.
  bool uses_sc() const { return torn_any_ || !split_trig_.empty(); }
  // The place of each coordinate's sin and cos in _sc (split_trig_, and the split torn
  // blocks' rows of _torn_trig before them), or -1.
  void index_sc();
  void declare_sc(std::ostringstream& os, bool fill);
  static std::string motion_name(bool velocity, bool acceleration) {
    return velocity && acceleration ? "solve_velocity_acceleration"
           : velocity               ? "solve_velocity"
                                    : "solve_acceleration";
  }
  // The arguments of a motion part: the public function's, then the report.
  static std::string motion_args(bool velocity, bool acceleration, bool declare);
  void call_parts(std::ostringstream& os, const std::string& name, const std::string& args);
  void part_header(std::ostringstream& os, const std::string& name, std::size_t k,
                   const std::string& params);
  void emit_position_parts(std::ostringstream& os);
  void emit_motion_parts(std::ostringstream& os, bool velocity, bool acceleration);
  void prologue(std::ostringstream& os) {
    os << kIn << "using R = _real<T>;\n";
    if (!used_.empty()) os << kIn << "using " << used_ << ";\n";
    os << kOptions << kIn << "BlockReport<R> report;\n";
  }
  void finite_check(std::ostringstream& os, const char* v) {
    os << kIn << "if (!_all_finite<nq>(" << v
       << ")) return _fail(report, _kStatusNonFinite, -1);\n";
    if (branches_ && std::string(v) == "q")
      os << kIn << "if (!_branches_hold(q, t, p)) return _fail(report, _kStatusBranchJump, -1);\n";
  }
  // Blocks [b0, b1).
  void position_body(std::ostringstream& os, FunctionPrinter& pr, int b0, int b1);
  void explicit_block(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                      const std::vector<int>& outputs);
  void newton_block(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi, int n_out,
                    const std::vector<int>& rotated);
  // |output o| as an entry of Phi_q's column col, in the column's units (lengths times their
  // coordinate scale), for the condition checks.
  std::string scaled_entry(FunctionPrinter& pr, int col, int o);
  // A guarded block's coefficient against its row's couplings to earlier blocks, at the solved
  // q: the block's condition within all of Phi_q (a coefficient that is small beside them is a
  // near-singular Phi_q although it is not zero). Recorded in the report's rcond.
  void guarded_condition(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi);
  // Newton blocks check what the dense path checks (kernels/newton.hpp): before the loop, the
  // state its last iteration leaves for the recheck: the row scales (_rmax), the columns'
  // scales (_d: lengths times length_scale), the scaled |q| sum, the condition estimate and
  // the determinant's sign of the last factorization, the iteration count and whether the step
  // criterion held.
  void newton_declare(std::ostringstream& os, std::size_t bi, const std::vector<int>& cols);
  // Whether a coordinate is a length (scaled by length_scale) rather than an angle.
  // Lengths (and scalars) are measured in units of their coordinate_scales entry, angles in
  // radians: the factor that does it in steps and roundings ("" for an angle), and the scale.
  bool length_coordinate(int c) const { return kinds_[c] != CoordinateKind::kAngle; }
  std::string inv_scale(int c) const {
    return length_coordinate(c) ? " * R(1 / " + ref("coordinate_scales", c) + ")" : "";
  }
  // The step criterion for block coordinate c (the update in _r[i]), with the rounding
  // allowance; adds its scaled |q| to _qs.
  void step_criterion(std::ostringstream& os, const std::string& in, int c, int i);
  // Counts the linear steps (the Newton policy's convergence-rate test) in _nl<b>.
  void linear_count(std::ostringstream& os, const std::string& in, const std::string& b,
                    const std::string& step);
  // The end of an iteration: stop when the step criterion holds (or the fixed budget is
  // spent), or at max_iterations; then keep what the recheck needs (`keep`: more of it).
  void newton_stop(std::ostringstream& os, const std::string& in, std::size_t bi, int k,
                   const std::vector<std::string>& keep);
  // After the loop: the residual rows (outputs) at the final q, scaled by the last row scales,
  // and the block's verdict (_newton_end).
  void newton_finish(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                     const std::vector<int>& rows, const std::string& step);
  // One Newton update inside an iteration: _r[] holds the residuals of a k x k system whose
  // matrix is `a` (row-major texts); leaves the step in _r, or reports a singular block.
  void newton_solve(std::ostringstream& os, const std::string& in, std::size_t bi, int k,
                    const std::vector<std::string>& a);
  // Block bi's k x k matrix `a` for the rates, kept as _a<bi> (k = 1: the divisor) or factored
  // into _a<bi>/_piv<bi>; reports a singular block.
  void factor(std::ostringstream& os, std::size_t bi, int k, const std::vector<std::string>& a);
  // In solve_step: block bi's k x k factors (and a torn block's tear sensitivities, _D) into
  // StepFactors.
  void save_factors(std::ostringstream& os, std::size_t bi, int k);
  // Whether solve_step keeps block bi's factors: a K x K or torn block solved in solve_step
  // or its parts, not in a repeated block's function (1 x 1 blocks need none: their
  // coefficient is an entry of Phi_q).
  bool kept_factors(std::size_t bi) const {
    const BlockPlan& plan = st_.plans[bi];
    return step_factors_ && roll_of_[bi] < 0 && (plan.torn() || plan.block.rows.size() > 1);
  }
  // A torn block's rows (or coordinates) in its rate solve's order: the assigned ones, then
  // the residual rows (the tears); another block's as in the structure tables.
  std::vector<int> torn_order(std::size_t bi, bool rows) const;
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
  std::vector<int> declare_rotations(std::ostringstream& os, FunctionPrinter& pr, const Block& b);
  // `T _sinC, _cosC` for a coordinate whose sin or cos the program uses, from the cache (see
  // _trig); later terms read them. Explicit coordinates (always = false) only when the function
  // being emitted needs them. Returns whether they were declared.
  bool declare_trig(std::ostringstream& os, FunctionPrinter& pr, int c, bool always);
  // In a function that has the trig cache (motion_trig_): sin and cos, from the cache, of the
  // coordinates block bi's rates read that are not yet in scope.
  void declare_motion_trig(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                           bool velocity, bool acceleration);
  // sin and cos, from the cache, of the coordinates that `outputs` read through sin or cos and
  // whose values are not yet in scope (a repeated block's coordinates, or an earlier part's).
  void declare_needed_trig(std::ostringstream& os, FunctionPrinter& pr,
                           const std::vector<int>& outputs);
  // The coordinates whose sin or cos the trees of `nodes` read and that are not yet in scope.
  // sin and cos of a coordinate another block solved: bound to _sc where they are there
  // (sc_ready_), else as declare_trig (in a split solver: into _sc, for the parts after).
  void trig_of(std::ostringstream& os, FunctionPrinter& pr, int c);
  // In a part of a split solver: the sin and cos in _sc of the coordinates earlier parts
  // solved that block bi's position reads.
  void bind_earlier_trig(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi);
  std::set<int> trig_read(FunctionPrinter& pr, const std::vector<int>& nodes) const;
  // In a split torn block's functions: `T& _sinC = _sc[..]` (and _cosC) for its coordinates
  // that `nodes` read or that are `updated`, then sin and cos from the cache of the other
  // coordinates `nodes` read.
  void torn_trig(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                 const std::vector<int>& nodes, const std::vector<int>& updated);
  // A split torn block's own code (its Newton loop, or its rates): sin and cos (in the
  // position first evaluated into _sc from the cache), and the terms of its residual rows that
  // do not read its coordinates.
  void torn_host_trig(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi, bool position);
  // The private functions of the split torn blocks (split_blocks), called in order from the
  // blocks' Newton loops and rates: each takes a run of the assigned coordinates.
  void emit_torn_parts(std::ostringstream& os, bool velocity, bool acceleration);
  // The parameters every part of a split torn block takes after its first.
  static constexpr const char* kTornPartParams =
      "[[maybe_unused]] T t, [[maybe_unused]] const Params& p,\n"
      "      [[maybe_unused]] T* trig, [[maybe_unused]] T* _sc";
  // One part function of torn block bi: `_torn<b>_<kind>_part<k>(params)`, its body printed by
  // `body` over the assigned coordinates `range`.
  void emit_torn_part(std::ostringstream& os, std::size_t bi, const std::string& kind,
                      std::size_t k, const std::pair<int, int>& range, const std::string& what,
                      const std::string& params, const std::function<void(FunctionPrinter&)>& body);
  // Part k of torn block bi's position: its assigned coordinates' values, then (when asked)
  // their sensitivities to the tears, for the Newton loop's Schur complement.
  void emit_torn_position_part(std::ostringstream& os, std::size_t bi, std::size_t k);
  // Part k of torn block bi's rates: the sensitivities to the tears (_D), the correction
  // x += _D x_tears, and qd and qdd with the tears' at zero.
  void emit_torn_rate_parts(std::ostringstream& os, std::size_t bi, std::size_t k, bool velocity,
                            bool acceleration);
  // q[c] = value, keeping the rotated sin and cos of q[c] current.
  void update(std::ostringstream& os, const std::string& in, const std::vector<int>& rotated, int c,
              const std::string& value);
  // Appends `coefficient * x` (a Phi_q output) to a sum's text, folding +-1; x empty: the
  // coefficient alone.
  void add_product(std::string& sum, FunctionPrinter& pr, int output, const std::string& x);
  // `-(sum) / coefficient` for an assigned row's constant coefficient (an output).
  std::string divide_negated(FunctionPrinter& pr, const std::string& sum, int output, bool negate);
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
  SensitivityName sensitivity_locals(std::size_t bi, const std::string& prefix) const;
  SensitivityName sensitivity_array(std::size_t bi, const std::string& array) const;
  // The sum over row r's block coordinates (but `skip`) of Phi_q * dq/dtear_j.
  std::string row_sum(FunctionPrinter& pr, std::size_t bi,
                      const std::map<std::pair<int, int>, int>& entries,
                      const std::map<int, std::vector<char>>& dep, const SensitivityName& d_name,
                      const std::map<int, int>& assigned_index, int r, int skip, std::size_t j);
  std::map<int, int> assigned_index(std::size_t bi) const;
  // Sensitivities of the assigned coordinates plan.assigned[a0..a1) to the tears (dq[c]/dq[tear
  // j], from the assigned rows in order: the rows stay satisfied), `declare` name = ...;.
  void sensitivities(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                     const std::map<std::pair<int, int>, int>& entries,
                     const std::map<int, std::vector<char>>& dep, const std::string& in,
                     const SensitivityName& d_name, const char* declare, int a0, int a1);
  // The tears' Jacobian (the Schur complement): the row-major text of the m x m matrix.
  std::vector<std::string> schur_matrix(FunctionPrinter& pr, std::size_t bi,
                                        const std::map<std::pair<int, int>, int>& entries,
                                        const std::map<int, std::vector<char>>& dep,
                                        const SensitivityName& d_name);
  // The sensitivities as `prefix<j>_<c>` terms and the Schur complement, for a whole block.
  std::vector<std::string> schur(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                                 const std::map<std::pair<int, int>, int>& entries,
                                 const std::string& in, const std::string& prefix);
  // Newton on a torn block's tears: each pass assigns the other coordinates from the tears,
  // then (unless converged) evaluates the residuals and the tears' Jacobian and updates them.
  void torn_position(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                     const std::vector<int>& rotated);
  // Blocks [b0, b1); checks: end with the finite checks of qd and qdd.
  void motion_body(std::ostringstream& os, FunctionPrinter& pr, bool velocity, bool acceleration,
                   int b0, int b1, bool checks);
  void solve_rows(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                  const std::vector<int>& rhs, const char* var);
  // Row i of block bi's rates: rhs minus its couplings to earlier blocks' `var`.
  std::string rate_rhs(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                       const std::vector<int>& rhs, const char* var, std::size_t i);
  // A torn block's row r: `rhs` minus the row's non-tear block entries times x (other than
  // `skip`).
  std::string reduced_rhs(FunctionPrinter& pr, std::size_t bi, const std::string& rhs, int r,
                          int skip, const char* var);
  // The tears' x from the reduced residual rows g and the Schur complement factored in
  // motion_body.
  void solve_tears(std::ostringstream& os, std::size_t bi, const std::vector<std::string>& g,
                   const char* var);
  // The assigned coordinates a0..a1 corrected by their sensitivities times the tears' x.
  void correct(std::ostringstream& os, std::size_t bi, const std::map<int, std::vector<char>>& dep,
               const SensitivityName& d_name, const char* var, int a0, int a1);
  // A split torn block's rates: the parts' particular solution, the tears in this function,
  // then the parts' corrections.
  void solve_torn_rows_split(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                             const std::vector<int>& rhs, const char* var);
  // A torn block's linear system (Phi_q x = rhs on the block): a particular solution with the
  // tears at zero through the assigned rows, the tears from the Schur complement factored in
  // motion_body, then the assigned coordinates corrected by their sensitivities.
  void solve_torn_rows(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                       const std::vector<std::string>& texts, const char* var);
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
  const std::vector<TornParts>& torn_parts_ = plan_.torn_parts;       // per block
  const std::vector<std::vector<int>>& torn_trig_ = plan_.torn_trig;  // {coordinate, slot}
  const bool torn_any_ = plan_.torn_any;                              // some torn block is split
  std::vector<int> local_;     // a repeated block's function: coordinate -> table slot
  int first_block_ = -1;       // a repeated block's function: the first block alike
  bool step_mode_ = false;     // emitting solve_step (motion terms follow position)
  bool motion_trig_ = false;   // the motion being emitted has the trig cache
  bool step_factors_ = false;  // solve_step takes StepFactors (the header has forces)
  bool branches_ = false;      // spatial files: the branch conditions after a position solve
  bool saving_ = false;        // emitting solve_step's rates: keep the factors
  // sin and cos of a coordinate are declared where first read (not where it is solved): with
  // repeated blocks, whose functions solve coordinates the caller reads.
  bool lazy_trig_ = false;
  std::vector<std::string> divisor_;
  // A split solver's sin and cos in _sc (uses_sc): per coordinate its index there, or -1;
  // the rows {coordinate, trig slot} of _split_trig (after the torn blocks' rows); while
  // parts are emitted, whether a coordinate's values are in _sc already, and which the
  // position parts leave there.
  std::vector<int> sc_index_;
  bool split_sc_ = false;  // a split solver without repeated blocks: sin and cos pass in _sc
  std::vector<std::vector<int>> split_trig_;
  std::vector<char> sc_ready_, sc_in_position_;
};

}  // namespace kinegen::codegen::emit_detail
