// The high-precision reference: position, velocity and acceleration analysis in CLN arithmetic
// (through GiNaC) on the symbolic expressions themselves, independent of the straight-line
// program, the runtime solver and double rounding. What the double analysis is measured
// against (`kinegen analyze --reference-digits N`, tests/test_reference.cpp, the benchmarks).
#pragma once

#include <ginac/ginac.h>

#include <array>
#include <functional>
#include <memory>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"

namespace kinegen::codegen {

// Fewer digits would leave too little room between the reference and double rounding.
inline constexpr int kMinReferenceDigits = 20;
inline constexpr int kMaxReferenceDigits = 1000;

// The exact rational value of a double (every finite double is one).
GiNaC::numeric exact_numeric(double value);

// Evaluates a model's symbolic Phi, Phi_q, nu and gamma (SymbolicModel, parameters substituted
// exactly) in CLN floating point with `digits` decimal digits. Each block is compiled once to a
// tape of GiNaC numerics (structurally equal subexpressions shared), so an evaluation builds no
// GiNaC expressions. Inputs and results are GiNaC numerics; set GiNaC::Digits is not needed.
class HighPrecisionEvaluator {
 public:
  using Vector = std::vector<GiNaC::numeric>;
  HighPrecisionEvaluator(const CompiledModel& model, int digits);
  ~HighPrecisionEvaluator();
  HighPrecisionEvaluator(const HighPrecisionEvaluator&) = delete;
  HighPrecisionEvaluator& operator=(const HighPrecisionEvaluator&) = delete;

  int digits() const { return digits_; }
  // A value converted to this evaluator's float format (exact values are rounded once).
  GiNaC::numeric to_float(const GiNaC::numeric& x) const;

  // Throw AnalysisError when a value is not real (sqrt of a negative number, asin(2), ...).
  Vector phi(const Vector& q, const GiNaC::numeric& t);
  // The structural non-zeros in SymbolicModel::phi_q order (= ModelPrograms jac_rows/cols).
  Vector phi_q_values(const Vector& q, const GiNaC::numeric& t);
  Vector nu(const Vector& q, const GiNaC::numeric& t);
  Vector gamma(const Vector& q, const Vector& qd, const GiNaC::numeric& t);

  // Further outputs (expressions in q, qd, t and the parameters, such as the applied
  // generalized forces), compiled like the others; the handle is for evaluate().
  int add_outputs(const std::vector<GiNaC::ex>& outputs);
  Vector evaluate(int handle, const Vector& q, const Vector& qd, const GiNaC::numeric& t);

 private:
  struct Tape;
  std::unique_ptr<Tape> build(const std::vector<GiNaC::ex>& outputs) const;
  Vector run(Tape& tape, const Vector& q, const Vector* qd, const GiNaC::numeric& t);

  const CompiledModel* model_;
  int digits_;
  int nq_;
  std::unique_ptr<Tape> phi_, phi_q_, nu_, gamma_;
  std::vector<std::unique_ptr<Tape>> extra_;
};

// A solved state in high precision, before rounding to double.
struct ReferenceRow {
  GiNaC::numeric t;
  std::vector<GiNaC::numeric> q, qd, qdd;
  std::vector<std::array<GiNaC::numeric, 6>> points;  // x, y, vx, vy, ax, ay per named point
  std::vector<std::array<GiNaC::numeric, 3>> outputs;  // value, v, a per output
  // Outputs that read velocities: their a is 0 here and nan once rounded (to_state_row).
  std::vector<bool> velocity_outputs;
  int newton_iterations = 0;                          // at this time step
};

// The row rounded to double (each value rounded once, to nearest).
StateRow to_state_row(const ReferenceRow& row);

// Same semantics as run_analysis: solves every time of the grid from q0 (the first) and from a
// Taylor predictor of the previous solution (the others), as the double analysis does, so both
// follow the same assembly branch; hands each row to `sink` as soon as it is solved, rounded
// to double. Newton stops at a scaled step of 10^-(digits - 5). Throws AnalysisError on
// failure and UsageError when digits is outside [kMinReferenceDigits, kMaxReferenceDigits].
void run_reference_analysis(const CompiledModel& model, const TimeGrid& grid, int digits,
                            const std::function<void(const StateRow&)>& sink);

struct ForceModel;

// `analyze --forces` on the reference: Phi_q^T lambda = Q solved in the reference's precision
// at each high-precision row, the columns in force_columns order (symbolic/forces.hpp).
class ReferenceForces {
 public:
  ReferenceForces(const CompiledModel& model, const ForceModel& forces, int digits);
  ~ReferenceForces();
  // Throws AnalysisError when Phi_q^T is singular at the row.
  std::vector<GiNaC::numeric> solve(const ReferenceRow& row);

 private:
  const CompiledModel* model_;
  const ForceModel* forces_;
  std::unique_ptr<HighPrecisionEvaluator> eval_;
  int applied_ = 0;
  struct Data;
  std::unique_ptr<Data> data_;
};

// The same, handing over the rows in high precision.
void run_reference_analysis_exact(const CompiledModel& model, const TimeGrid& grid, int digits,
                                  const std::function<void(const ReferenceRow&)>& sink);

}  // namespace kinegen::codegen
