// What `kinegen equilibrium`, `modes` and `linearize` share: the model with the
// free coordinates as the state and the run-time inputs kept as inputs, the check that it
// has free coordinates, the operating point of --at, the output's format, JSON pieces.
#pragma once

#include <Eigen/Dense>
#include <memory>
#include <string>
#include <vector>

#include "cli.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/linearize.hpp"
#include "kinegen/codegen/io/animate.hpp"

namespace kinegen::cli {

struct LinearSetup {
  std::unique_ptr<kc::CompiledModel> model;
  std::unique_ptr<kc::ForceModel> forces;
  std::unique_ptr<kc::Linearizer> linearizer;
  kc::OperatingPoint at;  // --at over the defaults: value0, v0, u = 0
};

// Loads the file for `command` (UsageError when it has no free coordinates), reads --at
// (`keys` the ones the command takes; checked before anything is solved) and builds the
// Linearizer at its t.
LinearSetup load_linear(const Common& c, const std::string& command, const std::string& at,
                        const std::vector<std::string>& keys);

// The format of -o: --format if given, else from the file's extension (.json, .csv), else
// `fallback`. UsageError for one the command does not write.
std::string output_format(const std::string& format, const std::string& output,
                          const std::string& fallback, const std::vector<std::string>& allowed);

// `kinegen animate --mode K`: mode K (1-based) of `kinegen modes` (about the equilibrium, or
// --at) drawn as q + a sin(2 pi tau) dq over one period, a chosen so that the largest free
// coordinate swings by `amplitude` radians or length scales; options.grid.steps frames.
int run_animate_mode(const Common& c, kc::AnimateOptions options, const std::string& output,
                     int mode, double amplitude, const std::string& at);

// A number as format_number writes it, -0 as 0.
std::string number(double v);
std::string json_number(double v);
std::string json_vector(const Eigen::VectorXd& v);
std::string json_matrix(const Eigen::MatrixXd& m);
std::string json_strings(const std::vector<std::string>& names);
// {"name": value, ...}
std::string json_object(const std::vector<std::string>& names, const Eigen::VectorXd& v);

}  // namespace kinegen::cli
