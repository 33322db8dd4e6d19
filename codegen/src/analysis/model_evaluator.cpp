#include "kinegen/codegen/analysis/model_evaluator.hpp"

namespace kinegen::codegen {

EvalResult evaluate(const CompiledModel& model, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                    double t) {
  const int nq = model.nq(), nc = model.nc();
  EvalResult r;
  ModelEvaluator<double> ev(model);
  r.phi.resize(nc);
  r.nu.resize(nc);
  r.gamma.resize(nc);
  r.phi_q = Eigen::MatrixXd::Zero(nc, nq);
  ev.phi(q.data(), t, r.phi.data());
  ev.jacobian(q.data(), t, r.phi_q);
  ev.nu(q.data(), t, r.nu.data());
  ev.gamma(q.data(), qd.data(), t, r.gamma.data());
  r.outputs.resize(model.programs().num_outputs);
  if (r.outputs.size() > 0) {
    ProgramEvaluator<double> program(model.programs().outputs);
    program.run(q.data(), qd.data(), t, model.params().data(), r.outputs.data());
  }
  return r;
}

}  // namespace kinegen::codegen
