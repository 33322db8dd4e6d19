// A mechanism compiled: every stage from the file to the straight-line programs and the
// structure, owned in one place for both consumers (the emitter and the analyses).
#pragma once

#include <Eigen/Dense>
#include <memory>
#include <string>
#include <vector>

#include "kinegen/codegen/base/progress.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "kinegen/codegen/program/program.hpp"
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
};

}  // namespace kinegen::codegen
