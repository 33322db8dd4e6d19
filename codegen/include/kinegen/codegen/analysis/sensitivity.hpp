// Parameter sensitivities of the solved position, the numeric half: Phi_p and the
// outputs' dO/dp (symbolic/sensitivity.hpp) lowered, dq/dp = -Phi_q^-1 Phi_p with the
// factorization of Phi_q at the converged q (run_analysis does the solve), and for the named
// points dC/dp = C_q dq/dp + dC/dp|explicit.
#pragma once

#include <Eigen/Dense>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/program/program.hpp"
#include "kinegen/codegen/symbolic/sensitivity.hpp"

namespace kinegen::codegen {

// What run_analysis needs to add sensitivities to each row.
struct SensitivityModel {
  std::vector<int> params;         // parameter indices, in the order asked for
  std::vector<std::string> names;  // their names
  Program phi_p;                   // nc * np outputs, as derive_phi_p orders them
  // d s'/dp of each named point's local offset, evaluated: point_ds[k][point].
  std::vector<std::vector<Eigen::Vector2d>> point_ds;
  // Spatial files: each point's, then each vector's local offset s' and d s'/dp (ds3[k]), in
  // the order of their CSV columns.
  std::vector<Eigen::Vector3d> local3;
  std::vector<std::vector<Eigen::Vector3d>> ds3;
  // Spatial suspensions: wheel_travel and track_change are measured from the design position,
  // so their d/dp subtract its own (outputs x np; zeros elsewhere, empty without outputs).
  Eigen::MatrixXd output_offsets;
  // The outputs' explicit dO/dp (np x outputs, parameter-major), then O_q (outputs x nq), as
  // derive_output_p orders them; empty without `outputs`.
  Program output_p;
  // Whether the outputs' sensitivities are computed (the CSV's d(O)/d(p)); tolerance needs
  // the positions' only.
  bool outputs = true;
};

// The index of the parameter `name`; a UsageError starting with `option` (the command-line
// option that named it) lists the parameters there are.
int find_parameter(const CompiledModel& model, const std::string& name, const std::string& option);

// Resolves `names` (the parameters in the order given) and lowers Phi_p, and with `outputs`
// the outputs' dO/dp. Throws UsageError naming an unknown or repeated parameter, and with
// `outputs` InputError for an output that reads velocities (its sensitivity would need
// dqd/dp). A parameter that nothing depends on is valid: its columns are zeros.
SensitivityModel build_sensitivity(const CompiledModel& model,
                                   const std::vector<std::string>& names, bool outputs = true);

// Splits "p1,p2,..." (the --sensitivity argument); empty items are a UsageError.
std::vector<std::string> split_parameter_list(const std::string& list);

// The points' total derivatives at q: dpoints (2 * points x np), rows x, y per point in file
// order, from dq_dp (nq x np). Spatial files: 3 rows (x, y, z) per point, then per vector.
void point_sensitivities(const CompiledModel& model, const SensitivityModel& sensitivity,
                         const Eigen::VectorXd& q, const Eigen::MatrixXd& dq_dp,
                         Eigen::MatrixXd& dpoints);

// The outputs' total derivatives dO/dp = O_q dq/dp + dO/dp|explicit at q, t: doutputs
// (outputs x np).
void output_sensitivities(const CompiledModel& model, const SensitivityModel& sensitivity, double t,
                          const Eigen::VectorXd& q, const Eigen::MatrixXd& dq_dp,
                          Eigen::MatrixXd& doutputs);

// The positions that sensitivities and tolerances report, in CSV order: coordinate_labels,
// then each point's `P.x, P.y` (spatial files: `P.x, P.y, P.z`, then each vector's
// `V.x, V.y, V.z`).
std::vector<std::string> position_quantities(const Mechanism& mechanism);

// A spatial model's points' and then vectors' local offsets s' (parameters substituted);
// empty for a planar one.
std::vector<Eigen::Vector3d> spatial_offsets(const CompiledModel& model);

// The values of position_quantities at a row: q, then the points' (and vectors') positions;
// `offsets` as spatial_offsets (the row's model's), unused for a planar file.
Eigen::VectorXd position_values(const Mechanism& mechanism,
                                const std::vector<Eigen::Vector3d>& offsets, const StateRow& row);

// The CSV column names the sensitivities add, in order: for each parameter, for each body
// `d(B.x)/d(p)`, `d(B.y)/d(p)`, `d(B.phi)/d(p)`, then for each point `d(P.x)/d(p)`,
// `d(P.y)/d(p)`, then for each output `d(O)/d(p)`; spatial files as position_quantities.
std::vector<std::string> sensitivity_columns(const Mechanism& mechanism,
                                             const std::vector<std::string>& names);

}  // namespace kinegen::codegen
