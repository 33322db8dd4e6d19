// The first solve of a spatial model (docs/format.md, Spatial mechanisms; docs/embedding.md,
// "First solves and branches"): every driver moves from its value at the start pose (a
// revolute_angle from its angle0) to its value f(t) in steps of at most continued_steps[k], each
// step solved by Newton from the last on the header's block-linear kernels. A residual
// continuation (Phi(q, t) = (1 - s) Phi(q0, t)) would not do here: a revolute_angle's row
// sin(f) (f_i . f_j) - cos(f) (g_i . f_j) also vanishes at theta = f + pi, and from an angle
// more than a quarter turn away the residual path ends there, on the mirrored assembly.
// Header-only, allocation-free; used by Solver (block_solver.hpp) for headers that have
// num_continued (spatial files).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

#include "kinegen/motion.hpp"
#include "kinegen/solver.hpp"

namespace kinegen::detail {

// Whether the header has the block-linear kernels with all blocks' factors kept
// (block_factor_begin), on which the first solve's continuation runs.
template <class Model, class = void>
struct HasBlockFactors : std::false_type {};
template <class Model>
struct HasBlockFactors<Model, std::void_t<decltype(Model::block_factor_begin)>> : std::true_type {};

// Whether a header carries its drivers' rows by value (spatial files with a block solver).
template <class Model, class = void>
struct HasContinuedDrivers : std::false_type {};
template <class Model>
struct HasContinuedDrivers<
    Model, std::void_t<decltype(Model::continued_rows), decltype(Model::block_factor_begin)>>
    : std::true_type {};

// A spatial header's branch conditions at q (true for headers without them): the dense path's
// check; the generated block solves check them themselves.
template <class Model, class = void>
struct HasBranches : std::false_type {};
template <class Model>
struct HasBranches<Model, std::void_t<decltype(Model::num_branches)>> : std::true_type {};
template <class Model, class Scalar>
bool branches_hold(const Scalar* q, Scalar t, const typename Model::Params& p) {
  if constexpr (HasBranches<Model>::value) {
    return Model::_branches_hold(q, t, p);
  } else {
    return true;
  }
}

// Each block's determinant sign from its factors (a, piv as _block_factor_all leaves them).
template <class Model, class Scalar>
void block_det_signs(const Scalar* a, const int* piv, signed char* signs) {
  for (int b = 0; b < Model::num_blocks; ++b) {
    const int b0 = Model::block_begin[b];
    Model::template _with_block_size<Model>(Model::block_begin[b + 1] - b0, [&](auto size) {
      constexpr int K = decltype(size)::value;
      signs[b] = static_cast<signed char>(
          Model::template _lu_det_sign<K>(a + Model::block_factor_begin[b], piv + b0));
    });
  }
}

// The steps the drivers need: values[k] their start, values[num_continued + k] their target
// (NaN when one is not finite).
template <class Model, class Scalar>
double continuation_count(const Scalar* values) {
  using std::abs;
  constexpr int kK = Model::num_continued;
  double steps = 1;
  for (int k = 0; k < kK; ++k) {
    const double need =
        std::ceil(static_cast<double>(abs(values[kK + k] - values[k])) / Model::continued_steps[k]);
    if (!(need <= steps)) steps = need;  // NaN sticks
  }
  return steps;
}

// q: the start pose in, the solution at t out (which the ordinary solve then refines and
// checks). Every block's determinant sign is held to its sign at the first step's solution
// (else Status::kBranchJump, as in the planar continuation).
template <class Model, class Scalar, class Vector, class BlockOptions>
Result continue_drivers(Vector& q, Scalar t, const typename Model::Params& p,
                        const SolverOptions& options, const BlockOptions& block_options) {
  using R = typename Eigen::NumTraits<Scalar>::Real;
  using std::abs;
  constexpr int kNq = Model::nq, kNc = Model::nc, kBlocks = Model::num_blocks;
  constexpr int kK = Model::num_continued;
  constexpr int kNnz = Model::jac_nnz > 0 ? Model::jac_nnz : 1;
  constexpr int kFactors =
      Model::block_factor_begin[kBlocks] > 0 ? Model::block_factor_begin[kBlocks] : 1;
  Result r;
  Scalar values[2 * kK], res[kNc], jac[kNnz], row[kNnz + 1], dq[kNq], a[kFactors];
  int piv[kNq];
  signed char start_signs[kBlocks] = {}, signs[kBlocks] = {};
  Model::_continued_values(q.data(), t, p, values);
  const double steps = continuation_count<Model>(values);
  if (!(steps == steps) || !q.allFinite()) {
    r.status = Status::kNonFinite;
    return r;
  }
  if (steps > kMaxContinuationSteps) {
    r.status = Status::kTooFar;
    return r;
  }
  const auto o = Model::template _options_as<R>(block_options);
  const int n = static_cast<int>(steps);
  const R eps = std::numeric_limits<R>::epsilon();
  const R tolerance = R(options.tolerance);
  for (int i = 1; i <= n; ++i) {
    bool converged = false;
    for (int it = 1; it <= options.max_iterations && !converged; ++it) {
      Model::phi(q.data(), t, p, res);
      Model::phi_q(q.data(), t, p, jac);
      for (int k = 0; k < kK; ++k) {
        const Scalar v = values[k] + (values[kK + k] - values[k]) * Scalar(i) / Scalar(n);
        Model::_continued_row(k, q.data(), v, p, row);
        res[Model::continued_rows[k]] = row[0];
        for (int e = 0; e < Model::continued_count[k]; ++e)
          jac[Model::continued_first[k] + e] = row[1 + e];
      }
      const auto report = Model::template _block_factor_all<Model>(jac, a, piv, o);
      if (report.status != 0) {
        r.status = static_cast<Status>(report.status);
        r.block = report.block;
        return r;
      }
      block_det_signs<Model>(a, piv, signs);
      if (!Model::template _block_forward_factored<Model>(jac, a, piv, res, dq, 1)) {
        r.status = Status::kNonFinite;
        return r;
      }
      converged = true;
      for (int k = 0; k < kNq; ++k) {
        const R scale = R(model_coordinate_scale<Model>(k));
        q[k] -= dq[k];
        converged = converged && kernels::NewtonKernel::_step_converged(
                                     R(abs(dq[k])) / scale, R(abs(q[k])) / scale, tolerance, eps);
      }
      r.iterations = std::max(r.iterations, it);
    }
    if (!q.allFinite()) {
      r.status = Status::kNonFinite;
      return r;
    }
    if (!converged) {
      r.status = Status::kMaxIterations;
      return r;
    }
    for (int b = 0; b < kBlocks; ++b) {
      if (i == 1) start_signs[b] = signs[b];
      if (signs[b] != start_signs[b]) {
        r.status = Status::kBranchJump;
        r.block = b;
        return r;
      }
    }
  }
  return r;
}

}  // namespace kinegen::detail
