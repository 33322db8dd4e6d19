// Parameter sensitivities, the symbolic half (see symbolic/sensitivity.hpp).
#include "kinegen/codegen/symbolic/sensitivity.hpp"

namespace kinegen::codegen {

std::vector<GiNaC::ex> derive_phi_p(const SymbolicModel& model, const SymbolTable& symbols,
                                    const std::vector<int>& params) {
  std::vector<GiNaC::ex> out;
  out.reserve(model.phi.size() * params.size());
  for (int p : params)
    for (const auto& row : model.phi) out.push_back(row.diff(symbols.param(p)));
  return out;
}

std::vector<GiNaC::ex> derive_output_p(const SymbolicModel& model, const SymbolTable& symbols,
                                       const std::vector<int>& params) {
  std::vector<GiNaC::ex> out;
  for (int p : params)
    for (const auto& o : model.output_values) out.push_back(o.diff(symbols.param(p)));
  out.insert(out.end(), model.output_q.begin(), model.output_q.end());
  return out;
}

}  // namespace kinegen::codegen
