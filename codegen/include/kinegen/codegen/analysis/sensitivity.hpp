// Parameter sensitivities of the solved position, the numeric half: Phi_p and the
// outputs' dO/dp (symbolic/sensitivity.hpp) lowered, dq/dp = -Phi_q^-1 Phi_p with the
// factorization of Phi_q at the converged q (run_analysis does the solve), and for the named
// points dC/dp = C_q dq/dp + dC/dp|explicit.
#pragma once

#include <Eigen/Dense>
#include <string>
#include <vector>

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
// order, from dq_dp (nq x np).
void point_sensitivities(const CompiledModel& model, const SensitivityModel& sensitivity,
                         const Eigen::VectorXd& q, const Eigen::MatrixXd& dq_dp,
                         Eigen::MatrixXd& dpoints);

// The outputs' total derivatives dO/dp = O_q dq/dp + dO/dp|explicit at q, t: doutputs
// (outputs x np).
void output_sensitivities(const CompiledModel& model, const SensitivityModel& sensitivity, double t,
                          const Eigen::VectorXd& q, const Eigen::MatrixXd& dq_dp,
                          Eigen::MatrixXd& doutputs);

// The positions that sensitivities and tolerances report, in CSV order: coordinate_labels,
// then each point's `P.x, P.y`.
std::vector<std::string> position_quantities(const Mechanism& mechanism);

// The CSV column names the sensitivities add, in order: for each parameter, for each body
// `d(B.x)/d(p)`, `d(B.y)/d(p)`, `d(B.phi)/d(p)`, then for each point `d(P.x)/d(p)`,
// `d(P.y)/d(p)`, then for each output `d(O)/d(p)`.
std::vector<std::string> sensitivity_columns(const Mechanism& mechanism,
                                             const std::vector<std::string>& names);

}  // namespace kinegen::codegen
