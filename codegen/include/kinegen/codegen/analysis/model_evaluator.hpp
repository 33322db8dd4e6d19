// A compiled model evaluated in process: its programs on any scalar type (ModelEvaluator),
// `kinegen eval`'s values (evaluate) and the runtime solver's view of it (ProgramSystem).
#pragma once

#include <Eigen/Dense>
#include <vector>

#include "kinegen/codegen/analysis/evaluator.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"

namespace kinegen::codegen {

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
    for (std::size_t k = 0; k < jac_values_.size(); ++k)
      jac(p.jac_rows[k], p.jac_cols[k]) = jac_values_[k];
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
