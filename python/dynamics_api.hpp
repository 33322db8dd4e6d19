// The Python module's dynamics: Mechanism.simulate, .dynamics, .equilibrium, .modes
// and .linearize, on the same library calls as `kinegen simulate`, `equilibrium`,
// `modes` and `linearize`, so their numbers are the command line's. The methods throw the
// library's errors (InputError, UsageError, AnalysisError), which the module turns into its
// exceptions.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/linearize.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"

namespace kinegen::python {

namespace py = pybind11;

using OptionalValues = std::optional<std::vector<double>>;

struct SimulateArgs {
  double t0 = 0, t1 = 0;
  int steps = 0;
  double rtol = 1e-8;
  std::optional<double> atol;  // default: 1e-2 rtol, as the command line's
  std::string method = "minimal", integrator = "auto";
  bool forces = false;
  bool allow_drift = false;
};

class DynamicsApi {
 public:
  // The model must outlive this object.
  explicit DynamicsApi(const codegen::CompiledModel& model);
  ~DynamicsApi();

  // Column name -> numpy array, simulate's CSV columns in their order; the warnings of the
  // run in *warnings. Runs without the GIL.
  py::dict simulate(const SimulateArgs& args, std::vector<std::string>& warnings);
  // zdd at (t, z, zd, u): the right-hand side of x' = f(x, u) that Mechanism.linearize
  // linearizes (u defaults to zeros).
  py::array_t<double> dynamics(double t, const std::vector<double>& z,
                               const std::vector<double>& zd, const OptionalValues& u);
  // Where the overdamped release from `start` (default value0) comes to rest, or with nearest
  // Newton's nearest root from it.
  py::dict equilibrium(double t, const OptionalValues& u, const OptionalValues& start = {},
                       bool nearest = false);
  py::dict modes(double t, const OptionalValues& z, const OptionalValues& u);
  py::dict linearize(double t, const OptionalValues& z, const OptionalValues& zd,
                     const OptionalValues& u);
  std::vector<std::string> free_names() const;
  std::vector<std::string> input_names() const;

 private:
  // A Linearizer whose t0 (ReducedDynamics' checks, value0's assembly) is t0; kept while it is.
  codegen::Linearizer& linearizer(double t0, const std::string& command);
  // The point: t, and z, zd, u where given (else value0, v0, zeros), their sizes checked.
  codegen::OperatingPoint point(codegen::Linearizer& lin, double t, const OptionalValues& z,
                                const OptionalValues& zd, const OptionalValues& u) const;

  const codegen::CompiledModel& model_;
  std::unique_ptr<codegen::ForceModel> forces_;
  std::unique_ptr<codegen::Linearizer> linearizer_;
  double t0_ = 0;
};

}  // namespace kinegen::python
