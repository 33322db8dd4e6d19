// A mechanism compiled: every stage from the file to the straight-line programs and the
// structure, owned in one place for both consumers (the emitter and the analyses).
#pragma once

#include <Eigen/Dense>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "kinegen/codegen/base/progress.hpp"
#include "kinegen/codegen/compile/programs.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "kinegen/codegen/program/program.hpp"
#include "kinegen/codegen/structure/block_program.hpp"
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

  // The block program of structure() (structure/block_program.hpp), for a structure the block
  // solver serves (a perfect matching); built on first use.
  const BlockProgram& block_program() const;

  // The programs beyond programs(), each built on first use and kept (programs.hpp).
  // The file's force model (derive_forces with the mechanism's masses, gravity and loads).
  const ForceModel& forces() const;
  // The programs of `forces`: the model's own, lowered once, when `forces` holds forces()'s
  // expressions (a derive_forces of this model with the file's ForceSpec does); another
  // ForceSpec's lowered for this call.
  std::shared_ptr<const ForcePrograms> force_programs(const ForceModel& forces) const;
  std::shared_ptr<const ForcePrograms> force_programs() const { return force_programs(forces()); }
  // The free items' value, rate, gradient and a0 programs.
  const FreePrograms& free_programs() const;
  // stop_when's g and rate (a model with stop_when).
  const StopPrograms& stop_programs() const;
  // The dynamics' tangent with `forces`' Q^A (the model's own computed once, as force_programs).
  std::shared_ptr<const TangentProgram> tangent_program(const ForceModel& forces) const;
  std::shared_ptr<const TangentProgram> tangent_program() const {
    return tangent_program(forces());
  }
  // The derivatives by the parameters `params` (SymbolTable indices, in their order), with the
  // outputs' where `outputs`; built once per list.
  const ParameterPrograms& parameter_programs(const std::vector<int>& params, bool outputs) const;

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
  mutable std::unique_ptr<BlockProgram> block_program_;
  // forces() and what is built from it; a ForceModel equal to forces() shares them.
  bool same_forces(const ForceModel& forces) const;
  mutable std::unique_ptr<ForceModel> forces_;
  mutable std::shared_ptr<const ForcePrograms> force_programs_;
  mutable std::shared_ptr<const TangentProgram> tangent_program_;
  mutable std::unique_ptr<FreePrograms> free_programs_;
  mutable std::unique_ptr<StopPrograms> stop_programs_;
  mutable std::map<std::pair<std::vector<int>, bool>, std::unique_ptr<ParameterPrograms>>
      parameter_programs_;
};

}  // namespace kinegen::codegen
