// The header's parameter sensitivities: phi_p and solve_sensitivity (emit_header's order is in
// emit_cpp.cpp).
#include <algorithm>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "kinegen/codegen/symbolic/sensitivity.hpp"
#include "printer.hpp"
#include "sections.hpp"

namespace kinegen::codegen::emit_detail {

// ---- Parameter sensitivities: Phi_p and dq/dp = -Phi_q^-1 Phi_p through the
// block structure, after a position solve.

// Each row's constraint, numbered in order of first appearance: the groups roll_outputs rolls.
std::vector<int> constraint_groups(const SymbolicModel& model) {
  std::map<const Constraint*, int> index;
  std::vector<int> group;
  for (const auto& row : model.rows)
    group.push_back(index.emplace(row.constraint, index.size()).first->second);
  return group;
}

// num_params, has_sensitivity, phi_p and solve_sensitivity. With --fold-params the code does
// not read Params, so there is nothing to differentiate: only the flags, false.
void emit_sensitivity(std::ostringstream& os, const CompiledModel& compiled,
                      const EmitOptions& options) {
  const SymbolTable& symbols = compiled.symbols();
  const SymbolicModel& model = compiled.symbolic();
  const int np = symbols.num_params();
  os << "\n  // Parameter sensitivities. num_params: the members of Params, in order\n"
     << "  // (parameter k is the k-th member).\n"
     << "  static constexpr int num_params = " << np << ";\n";
  if (compiled.build_options().fold_params) {
    os << "  // None: the parameters were folded into constants (--fold-params), so nothing here\n"
       << "  // depends on Params.\n"
       << "  static constexpr bool has_sensitivity = false;\n";
    return;
  }
  os << "  static constexpr bool has_sensitivity = true;\n\n";
  std::vector<int> params(np);
  for (int k = 0; k < np; ++k) params[k] = k;
  const ParameterPrograms& phi_p = compiled.parameter_programs(params, false);
  const std::vector<GiNaC::ex>& exprs = phi_p.phi_p_expressions;
  // Output k * nc + r is row r's derivative by parameter k: rows of one constraint by one
  // parameter form a group (alike constraints roll as in phi).
  const std::vector<int> rows = constraint_groups(model);
  const int groups = rows.empty() ? 0 : *std::max_element(rows.begin(), rows.end()) + 1;
  std::vector<int> group;
  for (int k = 0; k < np; ++k)
    for (int r : rows) group.push_back(k * groups + r);
  os << "  // Phi_p(q, t): out[k * nc + r] = dPhi_r/dp_k (nc x num_params, column-major).\n";
  if (np == 0) {
    os << "  template <class T>\n"
       << "  static void phi_p([[maybe_unused]] const T* q, [[maybe_unused]] T t,\n"
       << "      [[maybe_unused]] const Params& p, [[maybe_unused]] T* out) noexcept {}\n";
  } else {
    emit_function_rolled_if(os, "phi_p", "nc * num_params", phi_p.phi_p, exprs, group, symbols,
                            false, options.max_function_ops, options.roll_min);
  }
  os << "\n  // The work space of solve_sensitivity, in T's: Phi_q's entries, then -Phi_p.\n"
     << "  static constexpr int sensitivity_work_size = jac_nnz + nc * num_params;\n\n"
     << "  // Sensitivities of a solved position to the parameters: dq_dp[k * nq + i] = dq_i/dp_k\n"
     << "  // (nq x num_params, column-major) solves Phi_q dq/dp = -Phi_p at q, t, p, where q\n"
     << "  // is a converged solve_position (not re-checked). Phi_q is factored block by block,\n"
     << "  // once for all parameters (kinegen/kernels/block_linear.hpp); a singular or\n"
     << "  // ill-conditioned block (rcond at most options.min_rcond) fails with status 2 and its\n"
     << "  // index, a non-finite value with status 3, and dq_dp is then incomplete.\n"
     << "  // work: sensitivity_work_size values owned by the caller.\n"
     << "  template <class T, class U>\n"
     << "  static BlockReport<_real<T>> solve_sensitivity(const T* q, T t, const Params& p,\n"
     << "      T* dq_dp, const BasicBlockOptions<U>& options, T* work) noexcept {\n"
     << "    using R = _real<T>;\n"
     << "    T* const jac = work;\n"
     << "    T* const rhs = work + jac_nnz;\n"
     << "    phi_q(q, t, p, jac);\n"
     << "    phi_p(q, t, p, rhs);\n"
     << "    for (int k = 0; k < nc * num_params; ++k) rhs[k] = -rhs[k];\n"
     << "    return _block_forward<_model>(jac, rhs, dq_dp, num_params, _options_as<R>(options));\n"
     << "  }\n"
     << "  // The same with the work space on the stack: sizeof(T) * sensitivity_work_size bytes,\n"
     << "  // plus one block's matrix (max_block_size^2 T's) in the kernel.\n"
     << "  template <class T, class U>\n"
     << "  static BlockReport<_real<T>> solve_sensitivity(const T* q, T t, const Params& p,\n"
     << "      T* dq_dp, const BasicBlockOptions<U>& options) noexcept {\n"
     << "    T work[sensitivity_work_size];\n"
     << "    return solve_sensitivity(q, t, p, dq_dp, options, work);\n"
     << "  }\n";
}

}  // namespace kinegen::codegen::emit_detail
