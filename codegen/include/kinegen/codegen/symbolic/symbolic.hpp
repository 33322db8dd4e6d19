// The symbolic stage: one symbol table for every GiNaC symbol, the constraint library turned
// into Phi(q, t), and its derivatives Phi_q, nu = -Phi_t and
// gamma = -(Phi_q qd)_q qd - 2 Phi_qt qd - Phi_tt.
#pragma once

#include <ginac/ginac.h>

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "kinegen/codegen/model/mechanism.hpp"
#include "kinegen/motion.hpp"

namespace kinegen::codegen {

// What a symbol stands for in generated code and in the evaluator.
enum class InputKind { kQ, kQd, kT, kParam };
struct Input {
  InputKind kind;
  int index;  // coordinate or parameter index; 0 for t
};

// Which symbols an expression may use where it appears in the file.
enum class Scope {
  kConstant,    // numbers only: parameter values, --param overrides
  kGeometry,    // parameters: joint data, q0, point offsets
  kJoint,       // parameters and coordinates: expression joints
  kDriverTime,  // parameters and t: f(t) of a driver
  kDriver,      // parameters, coordinates and t: expression drivers
  kLoad,        // parameters, coordinates, velocities and t: force and torque loads
};

// A parameter whose value is an expression of earlier ones: not a symbol of its
// own, but that expression in the base parameters wherever its name is used, so that it moves
// with them (in generated code too, where it is not a member of Params).
struct DerivedParameter {
  std::string name;
  int source = 0;     // index in Mechanism::parameters
  GiNaC::ex value;    // in the base parameters' symbols
};

class SymbolTable {
 public:
  // `overridden`: the parameters given a value by --param; a derived one among them becomes a
  // base parameter (its formula dropped). Parses the derived parameters and the definitions
  // (InputError for a bad one).
  explicit SymbolTable(const Mechanism& mechanism, const std::vector<std::string>& overridden = {});
  SymbolTable(const SymbolTable&) = delete;
  SymbolTable& operator=(const SymbolTable&) = delete;

  const GiNaC::realsymbol& q(int k) const { return q_[k]; }
  const GiNaC::realsymbol& qd(int k) const { return qd_[k]; }
  const GiNaC::realsymbol& t() const { return t_; }
  const GiNaC::realsymbol& param(int k) const { return params_[k]; }
  int nq() const { return static_cast<int>(q_.size()); }
  int num_params() const { return static_cast<int>(params_.size()); }
  const std::string& param_name(int k) const { return param_names_[k]; }
  // The base parameter k's index in Mechanism::parameters.
  int param_source(int k) const { return param_source_[k]; }
  // The base parameter called `name`, or -1.
  int find_param(const std::string& name) const;
  const std::vector<DerivedParameter>& derived_params() const { return derived_; }
  const DerivedParameter* find_derived(const std::string& name) const;
  const std::string& coord_name(int k) const { return coord_names_[k]; }

  // Parses `expr` for use in `scope`: decimals become exact rationals, only the format's
  // functions are known, and every failure is an InputError naming `item` and the line.
  GiNaC::ex parse(const Expr& expr, Scope scope, const std::string& item) const;

  // The role of a symbol created here; throws std::logic_error for a foreign symbol.
  Input classify(const GiNaC::ex& symbol) const;

  // Names a derived quantity for the expressions parsed after: a free coordinate's value Z
  // and rate Z_d, which exist only once derive() has its equation. A name the file
  // already uses keeps its meaning (user names take precedence).
  void define(const std::string& name, const GiNaC::ex& value);
  // A name for a value supplied beside the parameters when an expression is evaluated in
  // process, not a model input (stop_when's force columns): it reads as parameter
  // num_params() + k, k counting these from 0. Returns k.
  int define_extra(const std::string& name);

 private:
  static bool has_symbol(const GiNaC::ex& e);
  // What an "unknown symbol" message adds: a velocity's name read as one (omega_<body>), or
  // the nearest name the scope allows.
  std::string unknown_symbol_hint(const std::string& name, Scope scope,
                                  const std::string& item) const;

  std::string source_;
  std::vector<GiNaC::realsymbol> q_, qd_, params_, extra_;
  GiNaC::realsymbol t_;
  std::vector<std::string> param_names_, coord_names_;
  std::vector<int> param_source_;
  std::vector<DerivedParameter> derived_;
  std::map<GiNaC::ex, Input, GiNaC::ex_is_less> roles_;
  // What each name in an expression stands for: coordinates and base parameters (symbols),
  // derived parameters and definitions (their expressions).
  std::map<std::string, GiNaC::ex> names_;
};

// One row of Phi and where it came from, for messages that name joints and drivers.
struct RowOrigin {
  const Constraint* constraint;
  int component;  // 0-based within the constraint
};

struct JacobianEntry {
  int row, col;
  GiNaC::ex value;
};

struct SymbolicModel {
  std::vector<GiNaC::ex> phi;            // nc
  std::vector<RowOrigin> rows;           // nc
  std::vector<JacobianEntry> phi_q;      // structural non-zeros, row-major
  std::vector<GiNaC::ex> nu;             // nc
  std::vector<GiNaC::ex> gamma;          // nc
  std::vector<GiNaC::ex> q0;             // nq, in the parameters
  std::vector<std::pair<GiNaC::ex, GiNaC::ex>> point_s;  // local offsets, in the parameters
  // Spatial files: each point's local offset and each named vector (Mechanism::vectors), as
  // [x, y, z] in the parameters (point_s then holds x and y).
  std::vector<std::vector<GiNaC::ex>> point_s3, vectors3;
  // Outputs, one entry each: the value O(q, t), its rate O_q qd + O_t, the part
  // of its acceleration without qdd (d/dt of the rate at qdd = 0), and O_q (dense, row-major
  // outputs x nq), so that the acceleration is output_q qdd + output_a0.
  // An output that reads velocities, O(q, qd, t): its rate is output_rates + output_qd qdd
  // (output_rates the part without qdd) and it has no acceleration (that would need the
  // jerk; output_a0 is 0). output_qd is O_qd (dense, row-major outputs x nq), empty when no
  // output reads a velocity, so that files without such outputs keep their programs.
  std::vector<GiNaC::ex> output_values, output_rates, output_a0, output_q, output_qd;
  std::vector<bool> output_reads_velocity;   // one per output
  std::vector<GiNaC::numeric> param_values;  // defaults (after overrides), exact
  // One line each (without "warning: "): a driver's boundary where f' or f'' jumps.
  std::vector<std::string> warnings;
  // What each coordinate measures (nq; bodies give length, length, angle; the extra
  // coordinates give their own kind) and the size its tolerances scale with: a body's
  // x and y scale with the geometry of its own joints and drivers, angles with 1.
  // Reported points and outputs never enter.
  std::vector<CoordinateKind> coordinate_kinds;
  std::vector<double> coordinate_scales;
  // The free coordinates, in Mechanism::free_drivers() order: the quantity each
  // measures as an expression in q (its value z) and its rate in q and qd.
  std::vector<GiNaC::ex> free_values, free_rates;
  // The largest length scale (the v1 header member; the solvers use coordinate_scales).
  double length_scale = 1.0;
  // A `suspension:` block's design_t (docs/format.md, Suspension analysis); 0 without one.
  double design_t = 0;
  // `stop_when:`, in q, qd, t, the parameters and, as extra parameters
  // (SymbolTable::define_extra), the force columns it reads: stop_force_columns[k] is the
  // force_columns index extra parameter k stands for. Empty when the file has none.
  GiNaC::ex stop_when;
  std::vector<int> stop_force_columns;
};

// Parses `stop_when` into model.stop_when: an expression in the coordinates and
// velocities by name (x_B, xd_B, ...), t, the parameters, the free coordinates (Z, Z_d), the
// outputs, and the CSV's columns by name (B.x, B.y, B.phi, B.vx, B.vy, B.omega, P.x, P.y,
// P.vx, P.vy, Z.v, O.v, and force columns such as J.fn or D.effort). Defines those names in
// `symbols` for it. InputError for an unknown name, naming the line.
void derive_stop_when(const Mechanism& mechanism, SymbolTable& symbols, SymbolicModel& model,
                      const std::vector<std::string>& force_columns);

// A --param NAME=VALUE override.
struct ParamOverride {
  std::string name;
  std::string value;
};

// Builds Phi and its derivatives. Defines each free coordinate's value Z and rate Z_d in
// `symbols` (loads, outputs and stop_when may read them). Throws InputError for bad
// expressions or overrides.
SymbolicModel derive(const Mechanism& mechanism, SymbolTable& symbols,
                     const std::vector<ParamOverride>& overrides = {});

// Substitutes the parameter values into `e` (exact where the values are exact).
GiNaC::ex substitute_params(const GiNaC::ex& e, const SymbolTable& symbols,
                            const std::vector<GiNaC::numeric>& values);

// Sets GiNaC's working precision (decimal digits) for a scope and restores it on exit, also
// when an evaluation throws.
class DigitsGuard {
 public:
  explicit DigitsGuard(long digits) : saved_(GiNaC::Digits) { GiNaC::Digits = digits; }
  ~DigitsGuard() { GiNaC::Digits = saved_; }
  DigitsGuard(const DigitsGuard&) = delete;
  DigitsGuard& operator=(const DigitsGuard&) = delete;

 private:
  long saved_;
};

// The double value of a constant expression (no symbols left).
double to_double(const GiNaC::ex& e);

// The structure stage expands equations to find the linear ones (structure.cpp): refuses,
// naming the constraint, a row whose expansion would have too many terms ((a + b + ... +
// p9)^40). CompiledModel calls it on the Phi the structure stage gets (after --fold-params), so
// every command refuses such a model alike.
void check_expansion_cost(const Mechanism& mechanism, const SymbolicModel& model);

}  // namespace kinegen::codegen
