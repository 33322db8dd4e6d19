// A mechanism compiled for in-process use: every stage from the file to the straight-line
// programs, and an adapter that lets the runtime's solver drive the programs directly.
#pragma once

#include <Eigen/Dense>
#include <memory>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/evaluator.hpp"
#include "kinegen/codegen/base/progress.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "kinegen/codegen/program/program.hpp"
#include "kinegen/codegen/structure/structure.hpp"
#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen {

struct BuildOptions {
  // Substitute the parameter values (after overrides) into Phi and its derivatives before
  // lowering, so they fold into literals (`kinegen generate --fold-params`). Params keeps its
  // members, but the programs no longer read them.
  bool fold_params = false;
  // Where the stages (reading, deriving, folding, lowering) report their progress.
  Progress progress;
  // Input drivers' tables (`analyze --input NAME=FILE.csv`): driver name, CSV path
  // (relative to the working directory). With inputs_required, an input driver without
  // one is a UsageError (every command but generate, whose code reads them from Params).
  std::vector<std::pair<std::string, std::string>> inputs;
  bool inputs_required = false;
  // The free coordinates are the state of a simulation, not inputs needing a table
  // (simulate, equilibrium, modes, linearize).
  bool free_as_state = false;
  // Spatial files (space: 3d) are taken only by the callers that handle them (eval, check,
  // analyze); the others refuse them, naming `user` ("`kinegen generate`").
  bool spatial = false;
  std::string user = "this command";
};

// Owns the stages; not copyable because later stages point into earlier ones.
class CompiledModel {
 public:
  // Reads, validates and derives; throws InputError.
  static std::unique_ptr<CompiledModel> from_file(const std::string& path,
                                                  const std::vector<ParamOverride>& overrides = {},
                                                  const BuildOptions& options = {});
  static std::unique_ptr<CompiledModel> from_mechanism(Mechanism mechanism,
                                                       const std::vector<ParamOverride>& overrides = {},
                                                       const BuildOptions& options = {});
  CompiledModel(const CompiledModel&) = delete;
  CompiledModel& operator=(const CompiledModel&) = delete;

  const Mechanism& mechanism() const { return mechanism_; }
  // What it was built with (its --input tables among them).
  const BuildOptions& build_options() const { return options_; }
  const SymbolTable& symbols() const { return *symbols_; }
  const SymbolicModel& symbolic() const { return symbolic_; }
  const ModelPrograms& programs() const { return programs_; }
  int nq() const { return programs_.nq; }
  int nc() const { return programs_.nc; }
  // The base parameters' values in double, in SymbolTable order (file order without the
  // derived parameters, which follow from these).
  const std::vector<double>& params() const { return params_; }
  // Every parameter, derived ones included, in file order, with its value.
  std::vector<std::pair<std::string, double>> parameter_table() const;
  // The same model with the named parameters' derived formulas dropped (each keeps its
  // present value: naming a derived parameter for a sensitivity treats it as overridden),
  // or nullptr when none of them is derived.
  std::unique_ptr<CompiledModel> with_base_parameters(const std::vector<std::string>& names) const;
  const std::vector<ParamOverride>& overrides() const { return overrides_; }
  Eigen::VectorXd q0() const;
  // Local offsets of the named points, evaluated.
  const std::vector<Eigen::Vector2d>& point_offsets() const { return point_s_; }

  // The value of a geometry expression of the file (parameters and constants) with the
  // parameters' values; `item` names it in an error.
  double geometry_number(const Expr& e, const std::string& item) const;

  // A label for the constraint behind row r, with the row's name when it has several
  // ("joints[1] (revolute) x-component (line 12)"; the names are the kind's row_name).
  std::string row_label(int row) const;

  // The block-lower-triangular structure of Phi (structure.hpp), computed on first use.
  const Structure& structure() const;

 private:
  explicit CompiledModel(Mechanism mechanism) : mechanism_(std::move(mechanism)) {}
  void build(const std::vector<ParamOverride>& overrides, const BuildOptions& options);

  Mechanism mechanism_;
  std::unique_ptr<SymbolTable> symbols_;
  SymbolicModel symbolic_;
  ModelPrograms programs_;
  std::vector<double> params_;
  std::vector<ParamOverride> overrides_;
  BuildOptions options_;
  std::vector<Eigen::Vector2d> point_s_;
  mutable std::unique_ptr<Structure> structure_;
};

// Evaluates a compiled model's programs on scalar type T (dense Phi_q).
template <class T>
class ModelEvaluator {
 public:
  using Vector = Eigen::Matrix<T, Eigen::Dynamic, 1>;
  using Matrix = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;

  explicit ModelEvaluator(const CompiledModel& model)
      : model_(&model),
        phi_(model.programs().phi),
        phi_q_(model.programs().phi_q),
        nu_(model.programs().nu),
        gamma_(model.programs().gamma),
        params_(model.params().begin(), model.params().end()),
        jac_values_(model.programs().jac_rows.size()) {}

  // The input drivers' values (ProgramEvaluator::set_inputs); not owned.
  void set_inputs(const T* inputs) {
    for (auto* p : {&phi_, &phi_q_, &nu_, &gamma_}) p->set_inputs(inputs);
  }
  void phi(const T* q, T t, T* out) { phi_.run(q, nullptr, t, params_.data(), out); }
  void nu(const T* q, T t, T* out) { nu_.run(q, nullptr, t, params_.data(), out); }
  void gamma(const T* q, const T* qd, T t, T* out) { gamma_.run(q, qd, t, params_.data(), out); }
  // The structural non-zeros in jac_rows/jac_cols order.
  void phi_q_values(const T* q, T t, T* out) { phi_q_.run(q, nullptr, t, params_.data(), out); }
  template <class M>
  void jacobian(const T* q, T t, M& jac) {
    phi_q_values(q, t, jac_values_.data());
    const auto& p = model_->programs();
    for (std::size_t k = 0; k < jac_values_.size(); ++k) jac(p.jac_rows[k], p.jac_cols[k]) = jac_values_[k];
  }

 private:
  const CompiledModel* model_;
  ProgramEvaluator<T> phi_, phi_q_, nu_, gamma_;
  std::vector<T> params_;
  std::vector<T> jac_values_;
};

// What `kinegen eval` prints (and the Python module's eval returns): Phi, the dense Phi_q, nu
// and gamma at (q, qd, t), and the outputs' values (empty without outputs).
struct EvalResult {
  Eigen::VectorXd phi, nu, gamma, outputs;
  Eigen::MatrixXd phi_q;
};
EvalResult evaluate(const CompiledModel& model, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                    double t);

// The runtime's view of a compiled model (sizes known at run time).
class ProgramSystem {
 public:
  using Scalar = double;
  static constexpr int kNq = Eigen::Dynamic;
  static constexpr int kNc = Eigen::Dynamic;

  explicit ProgramSystem(const CompiledModel& model) : model_(&model), eval_(model) {}
  ProgramSystem(const ProgramSystem& other) : model_(other.model_), eval_(*other.model_) {}

  int nq() const { return model_->nq(); }
  int nc() const { return model_->nc(); }
  // The input drivers' values (ProgramEvaluator::set_inputs); not owned.
  void set_inputs(const double* inputs) { eval_.set_inputs(inputs); }
  double length_scale() const { return model_->symbolic().length_scale; }
  double coordinate_scale(int k) const { return model_->symbolic().coordinate_scales[k]; }
  void phi(const double* q, double t, double* out) const { eval_.phi(q, t, out); }
  void nu(const double* q, double t, double* out) const { eval_.nu(q, t, out); }
  void gamma(const double* q, const double* qd, double t, double* out) const {
    eval_.gamma(q, qd, t, out);
  }
  template <class M>
  void jacobian(const double* q, double t, M& jac) const {
    eval_.jacobian(q, t, jac);
  }
  // Phi_q as structural non-zeros (the sparse path, kinegen/sparse_solver.hpp).
  int jacobian_nnz() const { return static_cast<int>(model_->programs().jac_rows.size()); }
  const int* jacobian_rows() const { return model_->programs().jac_rows.data(); }
  const int* jacobian_cols() const { return model_->programs().jac_cols.data(); }
  void jacobian_values(const double* q, double t, double* out) const {
    eval_.phi_q_values(q, t, out);
  }

 private:
  const CompiledModel* model_;
  mutable ModelEvaluator<double> eval_;  // scratch storage only
};

}  // namespace kinegen::codegen
