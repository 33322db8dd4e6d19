// kinegen runtime: the sparse path of the analysis, for large models whose sizes are known only
// at run time (the command line's in-process models).
//
// Same Newton iteration, scaling, Newton policy (kernels/newton.hpp) and Result as the dense
// path in solver.hpp (the algorithms there are reused; only the factorization differs): Phi_q is
// held as an Eigen::SparseMatrix on its structural non-zeros, ordered once (COLAMD, analyzePattern
// at construction) and factored with Eigen::SparseLU at each Newton iteration. Nothing of size nq x
// nq is ever formed.
//
// Allocation: the pattern, the ordering and the workspace vectors are allocated at
// construction; SparseLU::factorize and SparseLU::solve allocate their own working storage on
// every call (Eigen 3.4), so this path is not for the no-allocation (generated, fixed-size) use.
//
// A system for this path provides, besides phi, nu, gamma and length_scale, its Jacobian as
// structural non-zeros: jacobian_nnz(), jacobian_rows(), jacobian_cols() (each entry's row and
// column; no (row, column) twice) and jacobian_values(q, t, out) (the values in that order).
// Square systems only (nc == nq); redundant models stay on the dense path.
#pragma once

#include <Eigen/SparseCore>
#include <Eigen/SparseLU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>
#include <vector>

#include "kinegen/solver.hpp"

namespace kinegen {

namespace detail {

template <class Scalar>
struct SparseWorkspace {
  using VectorQ = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;
  using VectorC = VectorQ;
  using Matrix = Eigen::SparseMatrix<Scalar, Eigen::ColMajor, int>;
  using Lu = Eigen::SparseLU<Matrix, Eigen::COLAMDOrdering<int>>;
  // The generic solve in solver.hpp takes its square branch.
  static constexpr bool kMayBeRectangular = false;

  template <class System>
  explicit SparseWorkspace(const System& sys)
      : rows(sys.jacobian_rows(), sys.jacobian_rows() + sys.jacobian_nnz()),
        cols(sys.jacobian_cols(), sys.jacobian_cols() + sys.jacobian_nnz()),
        slot(rows.size()),
        values(static_cast<Eigen::Index>(rows.size())),
        rhs(sys.nc()),
        rhs_new(sys.nc()),
        row_scale(sys.nc()),
        row_work(sys.nc()),
        col_scale(sys.nq()),
        dq(sys.nq()),
        q_factored(sys.nq()),
        q_trial(sys.nq()),
        est_x(sys.nq()),
        est_y(sys.nq()),
        est_z(sys.nq()) {
    eigen_assert(sys.nq() == sys.nc() && "the sparse path needs nc == nq");
    for (int k = 0; k < col_scale.size(); ++k) col_scale[k] = Scalar(coordinate_scale(sys, k));
    std::vector<Eigen::Triplet<Scalar, int>> entries;
    entries.reserve(rows.size());
    for (std::size_t k = 0; k < rows.size(); ++k) entries.emplace_back(rows[k], cols[k], Scalar(1));
    scaled.resize(sys.nc(), sys.nq());
    scaled.setFromTriplets(entries.begin(), entries.end());
    scaled.makeCompressed();
    // Where each structural entry lives in the compressed storage (the pattern never changes).
    const int* outer = scaled.outerIndexPtr();
    const int* inner = scaled.innerIndexPtr();
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const int* first = inner + outer[cols[k]];
      const int* last = inner + outer[cols[k] + 1];
      slot[k] = static_cast<int>(std::lower_bound(first, last, rows[k]) - inner);
    }
    lu.analyzePattern(scaled);
  }

  int nq() const { return static_cast<int>(col_scale.size()); }

  std::vector<int> rows, cols;  // structural non-zeros of Phi_q
  std::vector<int> slot;        // entry k's index in scaled's value array
  VectorQ values;               // Phi_q's entries in pattern order (unscaled)
  Matrix scaled;                // R Phi_q D, as in the dense Workspace
  Lu lu;
  VectorC rhs, rhs_new;
  VectorC row_scale;  // R (1 / largest |entry| of the row of Phi_q D)
  VectorC row_work;   // per-row scratch
  VectorQ col_scale;  // D (each coordinate's scale: coordinate_scale)
  VectorQ dq;
  VectorQ q_factored;
  VectorQ q_trial;
  VectorQ est_x, est_y, est_z;
  Scalar t_factored = Scalar(0);
  bool factored = false;
  int det_sign = 0;
};

// Smallest / largest |U_jj| of the last SparseLU factorization (the diagonal of U sits in L's
// supernodes, as SparseLU::signDeterminant reads it).
template <class Lu>
double sparse_pivot_ratio(const Lu& lu) {
  const auto& l = lu.matrixL().m_mapL;
  using L = std::decay_t<decltype(l)>;
  double largest = 0, smallest = std::numeric_limits<double>::infinity();
  for (Eigen::Index j = 0; j < lu.cols(); ++j) {
    double d = 0;
    for (typename L::InnerIterator it(l, j); it; ++it)
      if (it.index() == j) {
        d = static_cast<double>(std::abs(it.value()));
        break;
      }
    largest = std::max(largest, d);
    smallest = std::min(smallest, d);
  }
  return largest > 0 ? smallest / largest : 0.0;
}

// hager_reciprocal_condition for the factored sparse scaled Phi_q (with SparseLU's solves).
template <class Scalar>
double reciprocal_condition(SparseWorkspace<Scalar>& ws) {
  const int n = ws.nq();
  double norm_a = 0;
  for (int j = 0; j < n; ++j) {
    double column = 0;
    for (typename SparseWorkspace<Scalar>::Matrix::InnerIterator it(ws.scaled, j); it; ++it)
      column += static_cast<double>(std::abs(it.value()));
    norm_a = std::max(norm_a, column);
  }
  return hager_reciprocal_condition(ws, norm_a, n);
}

// The sparse counterpart of factor() in solver.hpp (found by argument-dependent lookup from the
// shared Newton iteration): evaluates Phi_q's non-zeros, scales them as the dense path does and
// factors them numerically on the pattern ordered at construction.
template <class System, class Scalar, class VQ>
bool factor(const System& sys, SparseWorkspace<Scalar>& ws, const VQ& q, typename System::Scalar t,
            const SolverOptions& options, Result& result) {
  sys.jacobian_values(q.data(), t, ws.values.data());
  ws.factored = false;
  ws.det_sign = 0;
  if (!all_finite(ws.values)) {
    result.status = Status::kNonFinite;
    return false;
  }
  const int nnz = static_cast<int>(ws.rows.size());
  ws.row_work.setZero();
  for (int k = 0; k < nnz; ++k) {
    const Scalar v = std::abs(ws.values[k] * ws.col_scale[ws.cols[k]]);
    ws.row_work[ws.rows[k]] = std::max(ws.row_work[ws.rows[k]], v);
  }
  for (int r = 0; r < ws.row_scale.size(); ++r)
    ws.row_scale[r] = ws.row_work[r] > Scalar(0) ? Scalar(1) / ws.row_work[r] : Scalar(1);
  Scalar* stored = ws.scaled.valuePtr();
  for (int k = 0; k < nnz; ++k)
    stored[ws.slot[k]] = ws.values[k] * ws.col_scale[ws.cols[k]] * ws.row_scale[ws.rows[k]];
  const int nq = ws.nq();
  ws.lu.factorize(ws.scaled);
  if (ws.lu.info() != Eigen::Success) {  // an exactly zero pivot
    result.pivot_ratio = 0;
    result.condition = std::numeric_limits<double>::infinity();
    result.rank = nq - 1;  // at least
    result.status = Status::kSingular;
    return false;
  }
  result.pivot_ratio = sparse_pivot_ratio(ws.lu);
  const double rcond = result.pivot_ratio > 0 ? reciprocal_condition(ws) : 0.0;
  result.condition = rcond > 0 ? 1 / rcond : std::numeric_limits<double>::infinity();
  result.rank = nq;
  if (!(rcond > options.min_rcond) || !(result.pivot_ratio > options.singular_pivot_ratio)) {
    result.rank = nq - 1;  // at least
    result.status = Status::kSingular;
    return false;
  }
  ws.det_sign = static_cast<int>(ws.lu.signDeterminant());
  ws.q_factored = q;
  ws.t_factored = t;
  ws.factored = true;
  return true;
}

// scaled_residual() of solver.hpp over the structural non-zeros only.
template <class Scalar, class V, class VQ>
double scaled_residual(SparseWorkspace<Scalar>& ws, const V& phi, const VQ& q, double& rounding) {
  using Real = typename Eigen::NumTraits<typename V::Scalar>::Real;
  const double eps = static_cast<double>(std::numeric_limits<Real>::epsilon());
  ws.row_work.setZero();
  for (std::size_t k = 0; k < ws.rows.size(); ++k)
    ws.row_work[ws.rows[k]] += std::abs(ws.values[k]) * std::abs(q[ws.cols[k]]);
  double worst = 0;
  rounding = 0;
  for (int r = 0; r < phi.size(); ++r) {
    const double scale = static_cast<double>(std::abs(ws.row_scale[r]));
    const double round =
        kernels::NewtonKernel::_rounding(static_cast<double>(ws.row_work[r]) * scale, eps);
    const double excess = static_cast<double>(std::abs(phi[r])) * scale - round;
    worst = std::max(worst, excess);
    rounding = std::max(rounding, round);
  }
  return worst;
}

}  // namespace detail

// Position, velocity and acceleration analysis with a sparse LU of Phi_q: the interface of
// BasicSolver (solver.hpp), for large square systems with run-time sizes.
template <class System>
class SparseSolver {
 public:
  using Scalar = typename System::Scalar;
  using Vector = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;
  using Matrix = Eigen::SparseMatrix<Scalar, Eigen::ColMajor, int>;

  explicit SparseSolver(System system, SolverOptions options = {})
      : system_(std::move(system)), options_(options), ws_(system_) {}

  Result position(Vector& q, Scalar t) { return detail::position(system_, ws_, q, t, options_); }
  Result velocity(const Vector& q, Scalar t, Vector& qd) {
    return detail::velocity(system_, ws_, q, t, qd, options_);
  }
  Result acceleration(const Vector& q, const Vector& qd, Scalar t, Vector& qdd) {
    return detail::acceleration(system_, ws_, q, qd, t, qdd, options_);
  }

  const System& system() const { return system_; }
  System& system() { return system_; }
  const SolverOptions& options() const { return options_; }
  SolverOptions& options() { return options_; }
  // Phi_q as last evaluated (unscaled), built on request: for diagnostics, not the hot path.
  Matrix jacobian() const {
    Matrix jac(ws_.scaled.rows(), ws_.scaled.cols());
    std::vector<Eigen::Triplet<Scalar, int>> entries;
    entries.reserve(ws_.rows.size());
    for (std::size_t k = 0; k < ws_.rows.size(); ++k)
      entries.emplace_back(ws_.rows[k], ws_.cols[k], ws_.values[static_cast<Eigen::Index>(k)]);
    jac.setFromTriplets(entries.begin(), entries.end());
    return jac;
  }
  // Structural non-zeros of Phi_q, and of the L and U factors (fill-in) of the last
  // factorization.
  Eigen::Index jacobian_nonzeros() const { return ws_.scaled.nonZeros(); }
  Eigen::Index factor_nonzeros() const { return ws_.lu.nnzL() + ws_.lu.nnzU(); }
  // As BasicSolver::jacobian_sign: sign of det(Phi_q) at the last factorization (0 if unknown).
  int jacobian_sign() const { return ws_.det_sign; }

 private:
  System system_;
  SolverOptions options_;
  detail::SparseWorkspace<Scalar> ws_;
};

}  // namespace kinegen
