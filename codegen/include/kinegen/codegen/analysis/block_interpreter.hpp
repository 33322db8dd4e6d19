// The in-process block solver (analysis stage): runs the block program (block_program.hpp)
// the way the generated solve_step runs it, statement for statement, with the same kernels
// (runtime/include/kinegen/kernels/, compiled here rather than pasted), so that `kinegen
// analyze` and a generated kinegen::Solver give the same q, qd and qdd bit for bit. Every
// arithmetic step mirrors a line that emit/block_emitter.hpp's BlockEmitter prints; the two change
// together (tests/test_same_answers.cpp compares them on every example).
//
// What the bits depend on, and so what is mirrored: the order of each sum and product (node
// values come from ProgramEvaluator::node_value, the evaluator the header's functions are
// tested against), sin and cos of a coordinate from the sin/cos cache and rotated by each
// Newton update, and the sums the emitter composes from Phi_q entries (couplings to earlier
// blocks, a torn block's Schur complement). Headers split into parts (--max-function-ops) or
// with repeated blocks (--roll-min) run the same algorithm but read sin and cos of an earlier
// part's coordinates from the cache, so their last bits may differ.
#pragma once

#include <kinegen/kernels/report.hpp>
#include <memory>
#include <vector>

#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/structure/block_program.hpp"
#include "kinegen/codegen/structure/structure.hpp"

namespace kinegen::codegen {

class BlockInterpreter {
 public:
  using Report = kernels::ReportKernel::BlockReport<double>;
  using Options = kernels::ReportKernel::BasicBlockOptions<double>;
  // The largest Newton system (a block, or a torn block's tears) it runs: the kernels are
  // instantiated per size.
  static constexpr int kMaxNewton = 16;

  // Whether a model's structure can run here: a perfect BLT order (square, structurally
  // regular) whose Newton systems are at most kMaxNewton.
  static bool supported(const Structure& st);

  // The model must outlive the interpreter. Throws std::logic_error when !supported.
  explicit BlockInterpreter(const CompiledModel& model);
  ~BlockInterpreter();

  // One full step as the generated solve_step: q holds the start (the previous solution or a
  // prediction) and receives the solution; then qd and qdd. The sin/cos cache and the blocks'
  // determinant signs are kept from call to call, as kinegen::Solver keeps them.
  Report solve_step(double* q, double t, double* qd, double* qdd, const Options& o);
  // The phase the last failed solve_step failed in.
  enum class Phase { kPosition, kVelocity, kAcceleration };
  Phase failed_phase() const { return phase_; }
  static const char* to_string(Phase p) {
    return p == Phase::kPosition ? "position" : p == Phase::kVelocity ? "velocity" : "acceleration";
  }
  // Empties the sin/cos cache and forgets the determinant signs (kinegen::Solver::reset).
  void reset();
  // What solve_step carries from call to call, to put back after a solve that must leave no
  // trace (ReducedDynamics::keep).
  struct Memory {
    std::vector<double> trig;
    std::vector<signed char> signs;
  };
  void save(Memory& m) const {
    m.trig = trig_;
    m.signs = signs_;
  }
  void restore(const Memory& m) {
    trig_ = m.trig;
    signs_ = m.signs;
  }
  // The input drivers' values for the next steps (ProgramEvaluator::set_inputs: 3 per driver,
  // value, rate, acceleration), as a generated Params holds them. Not owned.
  void set_inputs(const double* inputs) { inputs_ = inputs; }

  const Structure& structure() const { return st_; }
  // The coordinates Newton iterates (the generated newton_coordinates).
  const std::vector<int>& newton_coordinates() const { return newton_coordinates_; }

 private:
  struct Run;
  struct Step;  // one solve_step's blocks (block_interpreter.cpp)
  const CompiledModel& model_;
  const Structure& st_;
  const BlockProgram& bp_;  // the compile stage's
  std::vector<int> newton_coordinates_;
  std::vector<double> trig_;       // 3 per slot: anchor, sin, cos (NaN: empty)
  std::vector<signed char> signs_;  // per block
  std::unique_ptr<Run> run_;        // the workspace of one step
  const double* inputs_ = nullptr;
  Phase phase_ = Phase::kPosition;
};

}  // namespace kinegen::codegen
