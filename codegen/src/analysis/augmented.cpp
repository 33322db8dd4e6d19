// The augmented Lagrangian method for singular positions (format 7.2): being written.
#include "kinegen/codegen/analysis/simulate.hpp"

namespace kinegen::codegen {

std::unique_ptr<MotionFormulation> augmented_formulation(const CompiledModel&, const ForceModel&,
                                                         double) {
  throw UsageError("--method augmented is not available yet");
}

}  // namespace kinegen::codegen
