// The Python module's dynamics (see dynamics_api.hpp).
#include "dynamics_api.hpp"

#include <pybind11/stl.h>

#include <cmath>
#include <cstdlib>

#include "kinegen/codegen/analysis/equilibrium.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/simulate.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "locked.hpp"

namespace kinegen::python {

namespace kc = kinegen::codegen;

namespace {

py::array_t<double> vector(const Eigen::VectorXd& v) {
  py::array_t<double> a(v.size());
  std::copy(v.data(), v.data() + v.size(), a.mutable_data());
  return a;
}

py::array_t<double> matrix(const Eigen::MatrixXd& m) {
  py::array_t<double> a({m.rows(), m.cols()});
  for (Eigen::Index r = 0; r < m.rows(); ++r)
    for (Eigen::Index c = 0; c < m.cols(); ++c) a.mutable_at(r, c) = m(r, c);
  return a;
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> items;
  for (std::size_t b = 0, e; b <= line.size(); b = e + 1) {
    e = std::min(line.find(',', b), line.size());
    items.push_back(line.substr(b, e - b));
  }
  return items;
}

Eigen::VectorXd values(const std::vector<double>& v, Eigen::Index n, const std::string& what,
                       const std::string& names) {
  if (static_cast<Eigen::Index>(v.size()) != n)
    throw kc::UsageError(what + " expects " + std::to_string(n) + " value" + (n == 1 ? "" : "s") +
                         " (" + names + "), got " + std::to_string(v.size()));
  // As the command line's --at: a point is finite numbers.
  for (std::size_t k = 0; k < v.size(); ++k)
    if (!std::isfinite(v[k]))
      throw kc::UsageError(what + "[" + std::to_string(k) + "] is " + kc::format_number(v[k]) +
                           ", not a finite number (" + what + ": " + names + ")");
  return Eigen::Map<const Eigen::VectorXd>(v.data(), n);
}

std::string joined(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s.empty() ? "none" : s;
}

// f() under the library's lock, without the GIL (locked.hpp): f touches no Python object.
template <class F>
auto under_lock(F&& f) {
  Locked locked;
  return f();
}

}  // namespace

DynamicsApi::DynamicsApi(const kc::CompiledModel& model) : model_(model) {}
DynamicsApi::~DynamicsApi() = default;

std::vector<std::string> DynamicsApi::free_names() const {
  return kc::free_names(model_.mechanism());
}

std::vector<std::string> DynamicsApi::input_names() const {
  return kc::input_names(model_.mechanism());
}

kc::Linearizer& DynamicsApi::linearizer(double t0, const std::string& command) {
  if (model_.mechanism().num_free() == 0)
    throw kc::UsageError("Mechanism." + command +
                         " needs free coordinates (`free:` lists the degrees of "
                         "freedom that the forces move), and the file has none");
  if (!std::isfinite(t0)) throw kc::UsageError("t must be finite");
  if (!forces_) forces_ = std::make_unique<kc::ForceModel>(kc::derive_forces(model_));
  if (!linearizer_ || t0 != t0_) {
    linearizer_ = std::make_unique<kc::Linearizer>(model_, *forces_, t0);
    t0_ = t0;
  }
  return *linearizer_;
}

kc::OperatingPoint DynamicsApi::point(kc::Linearizer& lin, double t, const OptionalValues& z,
                                      const OptionalValues& zd, const OptionalValues& u) const {
  if (!std::isfinite(t)) throw kc::UsageError("t must be finite");
  kc::OperatingPoint p = lin.initial();
  p.t = t;
  const std::string names = joined(free_names());
  if (z) p.z = values(*z, lin.nf(), "z", names);
  if (zd) p.zd = values(*zd, lin.nf(), "zd", names);
  if (u) p.u = values(*u, lin.nu(), "u", "the run-time inputs: " + joined(input_names()));
  return p;
}

py::dict DynamicsApi::simulate(const SimulateArgs& a, std::vector<std::string>& warnings) {
  // The command line's checks (cli/simulate.cpp) and its model: the free coordinates the
  // state, every input driver given its table.
  if (a.steps < 1) throw kc::UsageError("--steps must be at least 1");
  if (!std::isfinite(a.t0) || !std::isfinite(a.t1) || !(a.t1 > a.t0))
    throw kc::UsageError("t1 must come after t0, both finite: a simulation runs forward in time");
  kc::SimulateOptions options = kc::simulate_options(a.rtol, a.atol, a.method, a.integrator, "");
  options.allow_drift = a.allow_drift;
  std::vector<std::string> columns;
  std::vector<std::vector<double>> rows;
  {
    Locked locked;  // the library's work; the Python result is built after it
    {
      kc::Mechanism copy = model_.mechanism();
      kc::apply_inputs(copy, {}, true, true);
    }
    if (!forces_) forces_ = std::make_unique<kc::ForceModel>(kc::derive_forces(model_));
    std::vector<std::string> force_names;
    if (a.forces) {
      options.forces_columns = forces_.get();
      force_names = kc::force_columns(model_.mechanism());
    }
    std::string header = kc::simulate_csv_header(model_.mechanism(), force_names);
    header.pop_back();
    columns = split(header);
    // The rows are kept to be returned (the command line streams them): bounded as analyze's.
    kc::require_kept_rows("simulate", a.steps + 1LL, columns.size());
    const int nb = static_cast<int>(model_.mechanism().bodies.size());
    // As the CSV: the text parsed back (17 digits round-trip a double), so bit for bit.
    const kc::SimulateSummary summary = kc::run_simulation(
        model_, *forces_, {a.t0, a.t1, a.steps},
        [&](const kc::SimulatedRow& row) {
          std::string line = kc::simulate_csv_row(row, nb);
          line.pop_back();
          std::vector<double> v;
          for (const auto& item : split(line)) v.push_back(std::strtod(item.c_str(), nullptr));
          rows.push_back(std::move(v));
        },
        options);
    if (summary.drifted) warnings.push_back(model_.mechanism().source + ": " + summary.drift);
  }
  py::dict out;
  for (std::size_t c = 0; c < columns.size(); ++c) {
    py::array_t<double> col(static_cast<py::ssize_t>(rows.size()));
    for (std::size_t r = 0; r < rows.size(); ++r) col.mutable_data()[r] = rows[r][c];
    out[py::str(columns[c])] = col;
  }
  return out;
}

py::array_t<double> DynamicsApi::dynamics(double t, const std::vector<double>& z,
                                          const std::vector<double>& zd, const OptionalValues& u) {
  const Eigen::VectorXd zdd = under_lock([&] {
    kc::Linearizer& lin = linearizer(linearizer_ ? t0_ : t, "dynamics");
    const kc::OperatingPoint p = point(lin, t, z, zd, u);
    kc::MotionState state;
    const std::string where = model_.mechanism().source + ": dynamics at " + kc::format_time(t);
    if (!lin.evaluate(p, state)) throw kc::AnalysisError(where + ": " + lin.reason());
    // Finite inputs can still overflow the forces (an input of 1e308 on a mass below 1): a
    // zdd that is not finite is refused, never returned as a result.
    if (!state.zdd.allFinite()) {
      std::string values;
      for (Eigen::Index k = 0; k < state.zdd.size(); ++k) {
        if (k) values += ", ";
        values += kc::format_number(state.zdd[k]);
      }
      throw kc::AnalysisError(where + ": the accelerations zdd are not finite (" + values +
                              "): the forces at this point overflow a double (the inputs u or "
                              "the state z, zd too large)");
    }
    return state.zdd;
  });
  return vector(zdd);
}

py::dict DynamicsApi::equilibrium(double t, const OptionalValues& u, const OptionalValues& start,
                                  bool nearest) {
  std::vector<double> columns;
  const kc::Equilibrium e = under_lock([&] {
    // A fresh Linearizer, as the command line's: each solve starts from the last state solved,
    // so the release's path (and z to its last bit) would depend on earlier calls.
    linearizer_.reset();
    kc::Linearizer& lin = linearizer(t, "equilibrium");
    kc::Equilibrium found = kc::find_equilibrium(
        lin, point(lin, t, start, std::nullopt, u),
        nearest ? kc::EquilibriumSearch::kNearest : kc::EquilibriumSearch::kRest);
    kc::ForceSolver solver(model_, *forces_);
    solver.set_inputs(lin.dynamics().input_slots());
    solver.solve(found.at.t, found.state.q, found.state.qd, found.state.qdd, columns);
    return found;
  });
  py::dict forces;
  const auto names = kc::force_columns(model_.mechanism());
  for (std::size_t k = 0; k < names.size(); ++k) forces[py::str(names[k])] = columns[k];
  const kc::ReducedStiffness& r = e.stiffness;
  py::dict out;
  out["t"] = e.at.t;
  out["stability"] = kc::to_string(r.stability);
  out["free"] = free_names();
  out["z"] = vector(e.at.z);
  out["coordinates"] = kc::coordinate_labels(model_.mechanism());
  out["q"] = vector(e.state.q);
  out["forces"] = forces;
  out["mass"] = matrix(r.mass);
  out["stiffness"] = matrix(r.stiffness);
  out["stiffness_eigenvalues"] = vector(r.eigenvalues);
  out["unstable"] = r.unstable;
  out["neutral"] = r.neutral;
  out["iterations"] = e.iterations;
  out["flow_steps"] = e.flow_steps;
  out["left_start"] = e.left_start;
  out["residual"] = vector(e.force);
  return out;
}

py::dict DynamicsApi::modes(double t, const OptionalValues& z, const OptionalValues& u) {
  int nf = 0;
  const kc::ModalAnalysis a = under_lock([&] {
    linearizer_.reset();  // as in equilibrium()
    kc::Linearizer& lin = linearizer(t, "modes");
    nf = lin.nf();
    kc::OperatingPoint p = point(lin, t, z, std::nullopt, u);
    if (!z) p = kc::find_equilibrium(lin, p).at;
    return kc::modal_analysis(lin, p);
  });
  const Eigen::Index n = static_cast<Eigen::Index>(a.modes.size());
  Eigen::VectorXd f(n), fd(n), zeta(n);
  Eigen::MatrixXd shapes(n, model_.nq()), shapes_z(n, nf);
  std::vector<std::string> kinds;
  for (Eigen::Index k = 0; k < n; ++k) {
    const kc::Mode& m = a.modes[k];
    f[k] = m.frequency;
    fd[k] = m.damped_frequency;
    zeta[k] = m.damping_ratio;
    shapes.row(k) = m.dq.transpose();
    shapes_z.row(k) = m.dz.transpose();
    kinds.push_back(kc::to_string(m.kind));
  }
  py::dict out;
  out["t"] = a.at.t;
  out["equilibrium"] = !z.has_value();
  out["stability"] = kc::to_string(a.stability);
  out["free"] = free_names();
  out["z"] = vector(a.at.z);
  out["coordinates"] = kc::coordinate_labels(model_.mechanism());
  out["q"] = vector(a.state.q);
  out["mass"] = matrix(a.stiffness.mass);
  out["stiffness"] = matrix(a.stiffness.stiffness);
  out["damping"] = matrix(a.stiffness.damping);
  out["frequencies"] = vector(f);
  out["damped_frequencies"] = vector(fd);
  out["damping_ratios"] = vector(zeta);
  out["kinds"] = kinds;
  out["shapes"] = matrix(shapes);
  out["shapes_z"] = matrix(shapes_z);
  return out;
}

py::dict DynamicsApi::linearize(double t, const OptionalValues& z, const OptionalValues& zd,
                                const OptionalValues& u) {
  const kc::LinearModel l = under_lock([&] {
    kc::Linearizer& lin = linearizer(t, "linearize");
    return kc::linearize(lin, point(lin, t, z, zd, u));
  });
  py::dict out;
  out["t"] = l.at.t;
  out["states"] = l.states;
  out["inputs"] = l.inputs;
  out["x"] = vector(l.x);
  out["u"] = vector(l.at.u);
  out["xdot"] = vector(l.xdot);
  out["A"] = matrix(l.a);
  out["B"] = matrix(l.b);
  return out;
}

}  // namespace kinegen::python
