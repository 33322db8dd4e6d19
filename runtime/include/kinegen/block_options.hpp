// The block solvers' options from SolverOptions: one conversion, for the runtime's BlockSolver
// and Simulator and for the command line's block path (analysis/), so that every caller carries
// every option the same way.
#pragma once

#include <type_traits>
#include <utility>

#include "kinegen/solver.hpp"

namespace kinegen {

namespace detail {

// Options fields that older headers' BlockOptions lack.
template <class O, class = void>
struct OptionsHaveMinRcond : std::false_type {};
template <class O>
struct OptionsHaveMinRcond<O, std::void_t<decltype(std::declval<O&>().min_rcond)>>
    : std::true_type {};
template <class O, class = void>
struct OptionsHaveMaxHalvings : std::false_type {};
template <class O>
struct OptionsHaveMaxHalvings<O, std::void_t<decltype(std::declval<O&>().max_halvings)>>
    : std::true_type {};
template <class O, class = void>
struct OptionsHaveResidualTolerance : std::false_type {};
template <class O>
struct OptionsHaveResidualTolerance<O, std::void_t<decltype(std::declval<O&>().residual_tolerance)>>
    : std::true_type {};

}  // namespace detail

// SolverOptions as a header's (or the kernels') block options O: the one conversion, for
// BlockSolver, Simulator and the command line's block path alike. Fields that an older
// header's options lack (min_rcond, max_halvings, residual_tolerance) are left out.
template <class O>
O block_options_from(const SolverOptions& s) {
  O o;
  using R = decltype(o.tolerance);
  o.tolerance = static_cast<R>(s.tolerance);
  o.max_iterations = s.max_iterations;
  o.fixed_iterations = s.fixed_iterations;
  o.singular_pivot_ratio = static_cast<R>(s.singular_pivot_ratio);
  if constexpr (detail::OptionsHaveMinRcond<O>::value) o.min_rcond = static_cast<R>(s.min_rcond);
  if constexpr (detail::OptionsHaveMaxHalvings<O>::value) o.max_halvings = s.max_halvings;
  if constexpr (detail::OptionsHaveResidualTolerance<O>::value)
    o.residual_tolerance = static_cast<R>(s.residual_tolerance);
  return o;
}

}  // namespace kinegen
