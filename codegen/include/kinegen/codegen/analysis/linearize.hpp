// Linear models for control: A and B of x' = f(x, u) with x = (z, zd) and u the
// run-time inputs, exact (analysis/tangent.hpp), at an operating point given as `--at`.
//
// Takes: a Linearizer. Gives: LinearModel; the operating point's --at syntax and the names of
// x and u.
#pragma once

#include <Eigen/Dense>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/tangent.hpp"

namespace kinegen::codegen {

// Reads `--at`: comma-separated KEY=VALUE items, where KEY is t, or z, zd or u followed by
// their values in order (z=0.1,0.2), or one value by name: a free item Z (its rate Z.v or
// Z_d) or a run-time input. `keys` are the keys the command takes (of t, z, zd, u; a name
// counts as its vector's key); what the text does not set keeps its value in `base` (sized by
// the caller). UsageError, one line, for an unknown name (listing the known ones), a wrong
// count or a value that is not a finite number; `option` names the option in it.
OperatingPoint parse_operating_point(const Mechanism& m, const std::string& text,
                                     const std::vector<std::string>& keys, OperatingPoint base,
                                     const std::string& option = "--at");

// The names of the state x = (z, zd) of a linear model, as simulate's columns: Z, then Z.v.
std::vector<std::string> state_names(const Mechanism& m);
// The run-time inputs' names (run_inputs).
std::vector<std::string> input_names(const Mechanism& m);

struct LinearModel {
  OperatingPoint at;
  std::vector<std::string> states, inputs;  // x and u
  Eigen::VectorXd x, xdot;                  // (z, zd) and f(x, u) = (zd, zdd)
  Eigen::MatrixXd a, b;                     // 2 nf x 2 nf and 2 nf x nu (nu = 0: no columns)
  MotionState state;
};

// A and B at p: [0 I; d(zdd)/dz d(zdd)/dzd] and [0; d(zdd)/du]. AnalysisError naming the
// point when the state does not solve there.
LinearModel linearize(Linearizer& linearizer, const OperatingPoint& p);

}  // namespace kinegen::codegen
