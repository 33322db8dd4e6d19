// The tangent of the minimal-coordinates dynamics, in-process (see analysis/tangent.hpp).
#include "kinegen/codegen/analysis/tangent.hpp"

#include <Eigen/SparseLU>
#include <cmath>
#include <kinegen/kernels/block_linear.hpp>
#include <kinegen/kernels/linearize.hpp>

#include "block_tables.hpp"
#include "kinegen/codegen/analysis/evaluator.hpp"
#include "kinegen/codegen/base/format.hpp"

namespace kinegen::codegen {

namespace {

using K = kernels::LinearizeKernel;

// The pieces of the compile stage's TangentProgram, in its order.
enum Piece {
  kPhiQq,
  kNuQ,
  kGammaQ,
  kGammaQd,
  kPhiW,
  kNuW,
  kGammaW,
  kApplied,
  kAppliedQ,
  kAppliedQd,
  kAppliedW,
  kPieces
};

// The kernel with solves on one LU of all of Phi_q (where its blocks do not serve): dense up
// to 48 coordinates, sparse beyond.
int lu_tangent(const Eigen::MatrixXd& jac, const K::_TangentPoint<double>& p,
               const std::vector<int>& slots, Eigen::MatrixXd& out, std::vector<double>& work) {
  const Eigen::Index nq = jac.rows();
  const int ndir = static_cast<int>(slots.size());
  const auto in_place = [nq](auto&& solver, const double* b, double* x, int m) {
    Eigen::Map<Eigen::MatrixXd> cols(x, nq, m);
    cols = solver.solve(Eigen::Map<const Eigen::MatrixXd>(b, nq, m));
    return cols.allFinite() ? K::_kStatusConverged : K::_kStatusNonFinite;
  };
  if (nq <= 48) {
    const Eigen::PartialPivLU<Eigen::MatrixXd> lu(jac), lu_t(jac.transpose());
    return K::_dynamics_tangent(
        p, ndir, slots.data(), out.data(), work.data(),
        [&](double* b, double* x, int m) { return in_place(lu, b, x, m); },
        [&](double* b, double* x, int m) { return in_place(lu_t, b, x, m); });
  }
  const Eigen::SparseMatrix<double> sparse = jac.sparseView(), sparse_t = sparse.transpose();
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(sparse), lu_t(sparse_t);
  if (lu.info() != Eigen::Success || lu_t.info() != Eigen::Success) return K::_kStatusSingular;
  return K::_dynamics_tangent(
      p, ndir, slots.data(), out.data(), work.data(),
      [&](double* b, double* x, int m) { return in_place(lu, b, x, m); },
      [&](double* b, double* x, int m) { return in_place(lu_t, b, x, m); });
}

}  // namespace

struct Linearizer::Impl {
  Impl(const CompiledModel& model, const ForceModel& forces)
      : compiled(model.tangent_program(forces)),
        tangent(compiled->tangent),
        begin(compiled->begin),
        eval(compiled->program),
        values(compiled->program.outputs.size()),
        model_eval(model) {}

  std::shared_ptr<const TangentProgram> compiled;  // the compile stage's
  const TangentModel& tangent;
  const std::vector<int>& begin;  // of each Piece in the program's outputs
  ProgramEvaluator<double> eval;
  std::vector<double> values;
  ModelEvaluator<double> model_eval;
  std::vector<int> free_slot;
  std::unique_ptr<BlockTables> blocks;  // null where the blocks do not serve
  Eigen::MatrixXd jac;
  std::vector<double> jac_values;
  Eigen::VectorXd mass, inertia, ax, ay;
  std::vector<double> work;

  K::_Sparse<double> sparse(const SparseExpr& s, Piece p) const {
    return {static_cast<int>(s.row.size()), s.row.data(), s.col.data(), values.data() + begin[p]};
  }
  K::_TangentPoint<double> point(const ForceModel& f, const MotionState& s,
                                 const Eigen::MatrixXd& b) {
    const std::size_t nb = f.numbers.mass.size();
    mass.resize(nb);
    inertia.resize(nb);
    ax.resize(nb);
    ay.resize(nb);
    for (std::size_t k = 0; k < nb; ++k) {
      const double c = std::cos(s.q[3 * k + 2]), sn = std::sin(s.q[3 * k + 2]);
      const auto& com = f.numbers.com[k];
      mass[k] = f.numbers.mass[k];
      inertia[k] = f.numbers.inertia[k];
      ax[k] = c * com[0] - sn * com[1];
      ay[k] = sn * com[0] + c * com[1];
    }
    K::_TangentPoint<double> p;
    p.nq = static_cast<int>(s.q.size());
    p.nf = static_cast<int>(b.cols());
    p.nb = static_cast<int>(nb);
    p.q = s.q.data();
    p.qd = s.qd.data();
    p.qdd = s.qdd.data();
    p.b = b.data();
    p.mass = mass.data();
    p.inertia = inertia.data();
    p.ax = ax.data();
    p.ay = ay.data();
    p.applied = values.data() + begin[kApplied];
    const HessianExpr& h = tangent.phi_qq;
    p.phi_qq = {static_cast<int>(h.row.size()), h.row.data(), h.j.data(), h.k.data(),
                values.data() + begin[kPhiQq]};
    p.nu_q = sparse(tangent.nu_q, kNuQ);
    p.gamma_q = sparse(tangent.gamma_q, kGammaQ);
    p.gamma_qd = sparse(tangent.gamma_qd, kGammaQd);
    p.phi_w = sparse(tangent.phi_w, kPhiW);
    p.nu_w = sparse(tangent.nu_w, kNuW);
    p.gamma_w = sparse(tangent.gamma_w, kGammaW);
    p.applied_q = sparse(tangent.applied_q, kAppliedQ);
    p.applied_qd = sparse(tangent.applied_qd, kAppliedQd);
    p.applied_w = sparse(tangent.applied_w, kAppliedW);
    return p;
  }
};

Linearizer::Linearizer(const CompiledModel& model, const ForceModel& forces, double t0, bool blocks)
    : model_(model),
      forces_(forces),
      dynamics_(model, forces, t0),
      inputs_(run_inputs(model.mechanism())),
      impl_(std::make_unique<Impl>(model, forces)),
      last_(initial()) {
  impl_->eval.set_inputs(dynamics_.input_slots());
  impl_->model_eval.set_inputs(dynamics_.input_slots());
  for (int d : model.mechanism().free_drivers()) impl_->free_slot.push_back(3 * d);
  if (blocks && BlockTables::supported(model)) impl_->blocks = std::make_unique<BlockTables>(model);
}

Linearizer::~Linearizer() = default;

OperatingPoint Linearizer::initial() const {
  OperatingPoint p;
  p.t = dynamics_.initial().t;
  p.z = dynamics_.initial().z;
  p.zd = dynamics_.initial().zd;
  p.u = Eigen::VectorXd::Zero(nu());
  return p;
}

bool Linearizer::evaluate(const OperatingPoint& p, MotionState& state, Eigen::MatrixXd* d_z,
                          Eigen::MatrixXd* d_zd, Eigen::MatrixXd* d_u) {
  reason_.clear();
  for (int k = 0; k < nu(); ++k)
    if (!std::isfinite(p.u[k])) {
      reason_ = "the input " + inputs_[k].name + " is not finite";
      return false;
    }
  if (!solve_state(p, state)) return false;
  const int nf = dynamics_.nf();
  std::vector<int> wanted;
  for (int k : impl_->free_slot) wanted.push_back(k);
  for (int k : impl_->free_slot) wanted.push_back(k + 1);
  for (const RunInput& in : inputs_) wanted.push_back(in.slot);
  if (!d_z && !d_zd && !d_u) return true;
  Eigen::MatrixXd all;
  if (!tangent(state, wanted, all)) return false;
  if (d_z) *d_z = all.leftCols(nf);
  if (d_zd) *d_zd = all.middleCols(nf, nf);
  if (d_u) *d_u = all.rightCols(nu());
  return true;
}

bool Linearizer::solve_at(const OperatingPoint& p, MotionState& state) {
  double* slots = dynamics_.input_slots();
  for (int k = 0; k < nu(); ++k) slots[inputs_[k].slot] = p.u[k];
  if (!dynamics_.evaluate(p.t, p.z.data(), p.zd.data(), state)) {
    reason_ = dynamics_.reason();
    return false;
  }
  last_ = p;
  return true;
}

// A point far from the last one solved (the position solve's branch check refuses a jump
// that misses its first-order prediction) is reached along the straight line from it, as a
// motion would reach it, so that the solve stays on its branch.
bool Linearizer::solve_state(const OperatingPoint& p, MotionState& state) {
  if (solve_at(p, state)) return true;
  const MotionFailure f = dynamics_.failure();
  if (f != MotionFailure::kBranch && f != MotionFailure::kPosition) return false;
  const OperatingPoint from = last_;
  const auto between = [&](double s) {
    OperatingPoint x = p;
    x.t = from.t + s * (p.t - from.t);
    x.z = from.z + s * (p.z - from.z);
    x.zd = from.zd + s * (p.zd - from.zd);
    x.u = from.u + s * (p.u - from.u);
    return x;
  };
  double done = 0, step = 0.125;
  while (done < 1) {
    const double s = std::min(1.0, done + step);
    if (solve_at(s == 1 ? p : between(s), state)) {
      done = s;
      step = std::min(0.125, 2 * step);
    } else if ((step /= 2) < 1e-4) {
      return false;  // reason_: the failure where the walk stopped
    }
  }
  return true;
}

Eigen::MatrixXd Linearizer::reduced_mass(const MotionState& s) const {
  const Eigen::MatrixXd& b = dynamics_.b();
  const ForceData<double>& d = forces_.numbers;
  const int nb = static_cast<int>(d.mass.size()), nq = model_.nq();
  Eigen::VectorXd ax(nb), ay(nb);
  for (int k = 0; k < nb; ++k) {
    const double c = std::cos(s.q[3 * k + 2]), sn = std::sin(s.q[3 * k + 2]);
    ax[k] = c * d.com[k][0] - sn * d.com[k][1];
    ay[k] = sn * d.com[k][0] + c * d.com[k][1];
  }
  Eigen::MatrixXd mb(nq, b.cols());
  for (Eigen::Index k = 0; k < b.cols(); ++k)
    K::_mass_times(nb, nq, d.mass.data(), d.inertia.data(), ax.data(), ay.data(), b.col(k).data(),
                   mb.col(k).data());
  return b.transpose() * mb;
}

Eigen::VectorXd Linearizer::scales() const {
  const Mechanism& m = model_.mechanism();
  Eigen::VectorXd s(nf());
  int k = 0;
  for (int d : m.free_drivers()) {
    const std::string type = m.drivers[d].type_name();
    const bool angle = type == "absolute_angle" || type == "relative_angle";
    s[k++] = angle ? 1.0 : model_.symbolic().length_scale;
  }
  return s;
}

// The kernel on the state s (evaluate()'s), with solves on Phi_q there: through its blocks by
// the block_linear kernel, as generated code solves (each call factors every block once for
// all its columns), or where the blocks do not serve on one LU of all of Phi_q.
bool Linearizer::tangent(const MotionState& s, const std::vector<int>& slots,
                         Eigen::MatrixXd& out) {
  Impl& w = *impl_;
  const int nq = model_.nq(), nf = dynamics_.nf(), ndir = static_cast<int>(slots.size());
  // The derivatives at the state itself: the free items' acceleration slots hold zdd (the
  // dynamics solved with them at 0, for c), which gamma of a distance item reads (2 z zdd).
  double* inputs = dynamics_.input_slots();
  for (int k = 0; k < nf; ++k) inputs[w.free_slot[k] + 2] = s.zdd[k];
  w.eval.run(s.q.data(), s.qd.data(), s.t, model_.params().data(), w.values.data());
  for (int k = 0; k < nf; ++k) inputs[w.free_slot[k] + 2] = 0;
  const auto p = w.point(forces_, s, dynamics_.b());
  force_terms_ = dynamics_.b().cwiseAbs().transpose() *
                 Eigen::Map<const Eigen::VectorXd>(p.applied, nq).cwiseAbs();
  w.work.resize(K::_tangent_work_size(nq, nf, ndir));
  out.resize(nf, ndir);
  int status = 0;
  if (w.blocks) {
    w.jac_values.resize(model_.programs().jac_rows.size());
    w.model_eval.phi_q_values(s.q.data(), s.t, w.jac_values.data());
    const BlockTables::Binding bound(*w.blocks);
    const kernels::ReportKernel::BasicBlockOptions<double> options;
    using Linear = kernels::BlockLinearKernel;
    status = K::_dynamics_tangent(
        p, ndir, slots.data(), out.data(), w.work.data(),
        [&](double* b, double* x, int m) {
          return Linear::_block_forward<RuntimeBlocks>(w.jac_values.data(), b, x, m, options)
              .status;
        },
        [&](double* b, double* y, int m) {
          return Linear::_block_transposed<RuntimeBlocks>(w.jac_values.data(), b, y, m, options)
              .status;
        });
  } else {
    w.jac.setZero(nq, nq);
    w.model_eval.jacobian(s.q.data(), s.t, w.jac);
    status = lu_tangent(w.jac, p, slots, out, w.work);
  }
  if (status == 0) return true;
  reason_ = status == 2 ? "the tangent's solves failed: Phi_q or the reduced mass is singular"
                        : "a value of the tangent is not finite (a load, a table or the state)";
  return false;
}

}  // namespace kinegen::codegen
