// Position, velocity and acceleration analysis over a time grid, in-process, with the runtime's
// solver on a compiled model; and the CSV form of its rows.
#pragma once

#include <Eigen/Dense>
#include <array>
#include <functional>
#include <kinegen/motion.hpp>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/base/format.hpp"  // format_number, which CSV rows use

namespace kinegen::codegen {

// t_k = t0 + k (t1 - t0) / steps, k = 0..steps (one row at t0 when steps is 0).
struct TimeGrid {
  double t0 = 0, t1 = 0;
  int steps = 0;
  double at(int k) const { return steps == 0 ? t0 : t0 + k * (t1 - t0) / steps; }
};

struct PointState {
  Eigen::Vector2d r, v, a;
};

struct StateRow {
  double t = 0;
  Eigen::VectorXd q, qd, qdd;
  std::vector<PointState> points;
  // The outputs: value, velocity, acceleration, in file order.
  std::vector<std::array<double, 3>> outputs;
  // With AnalysisOptions::sensitivity: dq/dp (nq x np) and the points' dC/dp (2 per point,
  // x then y, x np); empty otherwise.
  Eigen::MatrixXd dq_dp, dpoints_dp;
  Eigen::MatrixXd doutputs_dp;  // outputs x np
  // With AnalysisOptions::forces: the force columns (force_columns order, symbolic/forces.hpp).
  std::vector<double> forces;
};

struct SensitivityModel;
struct ForceModel;

// Throws InputError when the model has fewer equations than coordinates (nc < nq). More
// equations are allowed: run_analysis checks them for redundancy at the assembled position.
void require_driven(const CompiledModel& model);

// What keeps its rows in memory (tolerance, animate, the Python module's analyze, the rows
// view's page keeps) holds at most this many numbers: 2^24, 128 MiB of doubles per copy.
// `analyze` and `simulate` on the command line stream their rows and have no such bound.
inline constexpr std::size_t kMaxKeptValues = std::size_t{1} << 24;
// Throws UsageError when `rows` rows of `per_row` numbers exceed kMaxKeptValues, naming `what`
// and the largest value of `option` that fits (--steps N keeps N + 1 rows).
void require_kept_rows(const std::string& what, long long rows, std::size_t per_row,
                       const std::string& option = "--steps");

struct AnalysisOptions {
  // Redundant (consistent) constraints are an error (InputError, exit 2) rather than a warning.
  bool strict = false;
  // Receives warnings (one line each, without the "warning: " prefix).
  std::function<void(const std::string&)> warn;
  // A converged position whose change since the last step disagrees with the velocities by
  // more than this fraction of the motion counts as a jump to another branch (an error).
  double jump_fraction = 0.25;
  // Off: neither the jump check nor the det(Phi_q) sign check (for tests that show what they
  // prevent).
  bool check_jumps = true;
  // A refused step (its solve failed, or it jumped) is taken in halves, each halved again while
  // refused, down to 1 / 2^substep_halvings of the step (kinegen::substeps, motion.hpp); the
  // rows are still those of the grid. The analysis fails where a sub-step that short is
  // refused: a singular configuration, or a motion the mechanism cannot follow. A generated
  // Solver with the same SolverOptions::substep_halvings takes the same sub-steps bit for bit.
  // 0: a refused step fails at once.
  int substep_halvings = kAnalyzeSubstepHalvings;
  // A solved position whose scaled Phi_q has a larger condition estimate is treated as
  // singular (a toggle that Newton converged onto): cond * eps would reach 1e-8.
  double max_condition = 1e8;
  // Square models with more coordinates than this are solved with a sparse LU of Phi_q
  // (kinegen/sparse_solver.hpp: no nq x nq matrix), smaller ones with the dense LU, whose
  // output is unchanged. Measured: the sparse path is faster from nq ~ 30, 2.5x at nq = 51
  // (docs/sparse_analysis.md). 0 sends every square model to the sparse path.
  int sparse_above_nq = 48;
  // Square models whose structure the block program covers (BlockInterpreter::supported) are
  // solved block by block, as generated code solves them, so that analyze and a generated
  // kinegen::Solver give the same numbers; false: the dense or sparse Newton on all of Phi_q
  // (an independent cross-check; redundant models always take it).
  bool block_solver = true;
  // Adds dq/dp and the points' dC/dp to every row (sensitivity.hpp), solved with the
  // factorization of Phi_q that the velocities use. Not owned; must outlive the call.
  const SensitivityModel* sensitivity = nullptr;
  // Adds the driver efforts and joint reactions to every row (forces.hpp): Phi_q^T lambda = Q
  // at the solved q, qd, qdd. Rows whose scaled condition estimate exceeds force_warning get
  // one warning (efforts grow without bound towards a toggle: a stated level, not a limit of
  // the arithmetic); a Phi_q singular by the rule of the generated solve_forces
  // (force_min_rcond, forces.hpp) fails the analysis there.
  const ForceModel* forces = nullptr;
  double force_warning = 1e3;
};

// Phi_q with rows equilibrated and columns multiplied by their coordinate's scale, as the
// solver sees it, so that its singular values and condition compare like with like (metres
// and radians): R J C. row_scale, if given, receives R's diagonal (1 / the row's largest
// scaled entry, 1 for a zero row).
Eigen::MatrixXd scaled_jacobian(const CompiledModel& model, const Eigen::MatrixXd& jac,
                                Eigen::VectorXd* row_scale = nullptr);

// The equations of a model with more equations than coordinates that depend on earlier ones
// (file order) at q, t, named by row_label and joined by "; "; empty when none do.
std::string redundant_constraints(const CompiledModel& model, const Eigen::VectorXd& q, double t);

// Solves every time of the grid, handing each row to `sink` as soon as it is solved, so a
// failure keeps what came before. Throws AnalysisError naming the file and time on failure.
// Singular or near-singular Phi_q (scaled condition estimate), contradictory constraints,
// Newton failures and jumps between assembly branches are AnalysisErrors; redundant
// constraints are warned about (or, with options.strict, an InputError before any row).
void run_analysis(const CompiledModel& model, const TimeGrid& grid,
                  const std::function<void(const StateRow&)>& sink);
void run_analysis(const CompiledModel& model, const TimeGrid& grid,
                  const std::function<void(const StateRow&)>& sink,
                  const AnalysisOptions& options);

// Position, velocity and acceleration of a point at local offset s on a body.
PointState point_state(const Eigen::Vector3d& q, const Eigen::Vector3d& qd,
                       const Eigen::Vector3d& qdd, const Eigen::Vector2d& s);

// Evaluates the outputs' values and exact time derivatives at a solved state:
// v = O_q qd + O_t, a = O_q qdd + (the rest of d/dt v); for an output that reads velocities
// v = O_q qd + O_qd qdd + O_t and a = nan. Allocates on construction only.
class OutputEvaluator {
 public:
  explicit OutputEvaluator(const CompiledModel& model);
  void evaluate(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                const Eigen::VectorXd& qdd, std::vector<std::array<double, 3>>& out);

 private:
  int nq_, n_;
  std::vector<double> params_, values_, rates_;
  std::vector<bool> reads_velocity_;
  ProgramEvaluator<double> value_program_, rate_program_;
};

std::string csv_header(const Mechanism& mechanism);
// With the sensitivity columns of these parameters after all others.
std::string csv_header(const Mechanism& mechanism, const std::vector<std::string>& sensitivity);
// With the force columns (forces.hpp) before the sensitivity columns.
std::string csv_header(const Mechanism& mechanism, const std::vector<std::string>& forces,
                       const std::vector<std::string>& sensitivity);
// Sensitivity columns follow when the row has them.
// `num_bodies`: the mechanism's; the coordinates after the bodies' are its extra ones.
std::string csv_row(const StateRow& row, int num_bodies);

}  // namespace kinegen::codegen
