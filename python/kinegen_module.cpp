// The Python module `kinegen`: a mechanism file compiled in-process, with the command line's
// analyses. Every number comes from the same library calls as `kinegen analyze` / `eval` /
// `check` / `generate` (analysis.hpp, compiled_model.hpp, check.hpp, emit_cpp.hpp), and analyze's
// columns are parsed back from the same csv_row text, so the results equal the CSV's bit for
// bit (17 significant digits round-trip a double) and follow its column order by construction.
// Errors raise kinegen.InputError (exit 2 on the command line), kinegen.UsageError (2) or
// kinegen.AnalysisError (1), each carrying the text of the command line's `error:` line.
// Threads: every method does its library work inside a `Locked` scope (locked.hpp): the GIL
// released, then the process-wide library lock taken, Ctrl-C checked; no Python object is
// touched inside. A new method follows the same pattern: `translate(path_, [&] { Locked
// locked; ... })`, then builds its Python result.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <regex>
#include <string>
#include <utility>
#include <vector>

#include "dynamics_api.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/analysis_rows.hpp"
#include "kinegen/codegen/analysis/check.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/analysis/sensitivity.hpp"
#include "kinegen/codegen/base/interrupt.hpp"
#include "kinegen/codegen/emit/emit_cpp.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "locked.hpp"
#include "view_page.hpp"

namespace py = pybind11;
namespace kc = kinegen::codegen;
namespace fs = std::filesystem;
using kinegen::python::Locked;

namespace {

// As the command line prints them: user text may hold line breaks; an error stays one line.
std::string one_line(std::string text) {
  for (char& ch : text)
    if (ch == '\n' || ch == '\r' || ch == '\t') ch = ' ';
  return text;
}

// The library's messages name the command line's flags (--param l, --steps); from Python
// they are the call's arguments (params['l'], steps).
std::string python_names(std::string text) {
  static const std::pair<std::regex, const char*> kFlags[] = {
      {std::regex(R"(--param ([A-Za-z_][A-Za-z0-9_]*))"), "params['$1']"},
      {std::regex(R"(--input ([A-Za-z_][A-Za-z0-9_]*)=FILE\.csv)"), "inputs={'$1': 'FILE.csv'}"},
      {std::regex(R"(--input ([A-Za-z_][A-Za-z0-9_]*))"), "inputs['$1']"},
      {std::regex(R"(\(--steps\))"), "(more steps)"},
      {std::regex(R"(--(t0|t1|steps|samples|sensitivity)\b)"), "$1"},
      {std::regex(R"(--forces\b)"), "forces=True"},
  };
  for (const auto& [flag, name] : kFlags) text = std::regex_replace(text, flag, name);
  return text;
}

// Exception types, alive as long as the module (handles: never released at interpreter exit).
py::handle input_error, usage_error, analysis_error;

// Runs `f`, turning the library's errors into the Python exceptions with the command line's
// message (cli/main.cpp: usage errors found after reading a file are prefixed with it), and an
// interrupted call into the exception its signal handler raised (KeyboardInterrupt). Runs with
// the GIL; a `Locked` scope inside `f` has given it back by the time an error arrives here.
template <class F>
auto translate(const std::string& file, F&& f) -> decltype(f()) {
  std::string message;
  py::handle* type = nullptr;
  try {
    return f();
  } catch (const kc::Interrupted&) {
    if (!PyErr_Occurred()) PyErr_SetNone(PyExc_KeyboardInterrupt);
    throw py::error_already_set();
  } catch (const kc::InputError& e) {
    message = one_line(e.what());
    type = &input_error;
  } catch (const kc::UsageError& e) {
    message = one_line(file + ": " + e.what());
    type = &usage_error;
  } catch (const kc::AnalysisError& e) {
    message = one_line(e.what());
    type = &analysis_error;
  }
  PyErr_SetString(type->ptr(), python_names(message).c_str());
  throw py::error_already_set();
}

// Each warning through Python's warnings module (UserWarning), as the command line prints its
// `warning:` lines.
void warn_all(const std::vector<std::string>& warnings) {
  if (warnings.empty()) return;
  const py::object warn = py::module_::import("warnings").attr("warn");
  for (const auto& w : warnings) warn(python_names(one_line(w)));
}

// A list of names (sensitivity=[...]): any iterable of str, but not a str, whose letters
// pybind11 would otherwise refuse with a message about the function's signature.
std::vector<std::string> names_of(const py::object& value, const char* argument) {
  const std::string usage = std::string(argument) + " expects a list of parameter names, e.g. " +
                            argument + "=['e', 'l']";
  if (value.is_none()) return {};
  if (py::isinstance<py::str>(value))
    throw py::type_error(usage + ", not the string '" + value.cast<std::string>() + "'");
  if (!py::isinstance<py::iterable>(value))
    throw py::type_error(usage + ", not " +
                         std::string(py::str(py::type::of(value).attr("__name__"))));
  std::vector<std::string> names;
  for (const py::handle item : value) {
    if (!py::isinstance<py::str>(item))
      throw py::type_error(usage + "; " + std::string(py::repr(item)) + " is not a str");
    names.push_back(item.cast<std::string>());
  }
  return names;
}

// params={name: value}: the command line's --param NAME=VALUE. A key that is not a str, or a
// value that is neither a number nor an expression string, is a TypeError that says so in
// Python's terms (the library would report "--param 1", and pybind11 a bare cast error).
std::vector<kc::ParamOverride> overrides_of(const py::dict& params) {
  std::vector<kc::ParamOverride> out;
  for (const auto& [key, value] : params) {
    if (!py::isinstance<py::str>(key))
      throw py::type_error("params: the key " + std::string(py::repr(key)) + " (" +
                           std::string(py::str(py::type::of(key).attr("__name__"))) +
                           ") is not a parameter name; params maps parameter names (str) to "
                           "numbers or expression strings, e.g. params={'l': 2.0}");
    const std::string name = key.cast<std::string>();
    // A number as the command line would read it back (17 digits: the same double), or an
    // expression as text.
    if (py::isinstance<py::str>(value)) {
      out.push_back({name, value.cast<std::string>()});
      continue;
    }
    double number = 0;
    try {
      number = value.cast<double>();
    } catch (const py::cast_error&) {
      throw py::type_error("params['" + name + "'] expects a number or an expression string, not " +
                           std::string(py::str(py::type::of(value).attr("__name__"))) + " " +
                           std::string(py::repr(value)));
    }
    out.push_back({name, kc::format_number(number)});
  }
  return out;
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> items;
  std::size_t begin = 0;
  while (true) {
    const std::size_t end = line.find(',', begin);
    items.push_back(line.substr(begin, end == std::string::npos ? end : end - begin));
    if (end == std::string::npos) return items;
    begin = end + 1;
  }
}

// As the command line's grid check: every t0 + k (t1 - t0) / steps must be a number, so the
// span of two finite times must be one too (-1e308 to 1e308 is not).
void check_span(double t0, double t1) {
  if (std::isfinite(t0) && std::isfinite(t1) && !std::isfinite(t1 - t0))
    throw kc::UsageError("--t1 - --t0 overflows (" + kc::format_number(t1) + " - " +
                         kc::format_number(t0) +
                         "); the times must be within about 1e308 of each other");
}

py::array_t<double> to_numpy(const Eigen::VectorXd& v) {
  py::array_t<double> a(v.size());
  std::copy(v.data(), v.data() + v.size(), a.mutable_data());
  return a;
}

class Mechanism {
 public:
  // inputs: an input driver's table (`--input NAME=FILE.csv`) by its name. As on the command
  // line, eval, check and generate take a missing input as 0 (a default Params), and analyze
  // needs every one.
  Mechanism(std::string path, py::dict params, py::dict inputs) : path_(std::move(path)) {
    overrides_ = overrides_of(params);
    for (const auto& [name, file] : inputs) {
      if (!py::isinstance<py::str>(name))
        throw py::type_error("inputs: the key " + std::string(py::repr(name)) +
                             " is not an input's name; inputs maps input names (str) to CSV "
                             "paths, e.g. inputs={'crank': 'crank.csv'}");
      build_.inputs.emplace_back(py::str(name), py::str(file));
    }
    // Spatial files as the command line takes them: each method refuses what they lack.
    build_.spatial = true;
    std::vector<std::string> warnings;
    translate(path_, [&] {
      Locked locked;
      model_ = kc::CompiledModel::from_file(path_, overrides_, build_);
      // What the properties read, kept here so that they need neither lock nor GiNaC.
      name_ = model_->mechanism().name;
      nq_ = model_->nq();
      nc_ = model_->nc();
      coordinates_ = kc::coordinate_labels(model_->mechanism());
      parameters_ = model_->parameter_table();
      warnings = model_->symbolic().warnings;
      spatial_ = model_->mechanism().spatial;
      space_loc_ = model_->mechanism().space_loc;
    });
    // The file's warnings (a jump at a driver's boundary), as the command line prints them
    // when it loads the file.
    warn_all(warnings);
  }

  // A CompiledModel holds GiNaC expressions, whose reference counts other threads' calls share:
  // it is destroyed under the library's lock too.
  ~Mechanism() {
    Locked locked(false);
    model_.reset();
  }
  Mechanism(const Mechanism&) = delete;
  Mechanism& operator=(const Mechanism&) = delete;

  // Column name -> numpy array, in the CSV's column order (a dict keeps insertion order).
  py::dict analyze(double t0, double t1, int steps, bool forces,
                   const std::vector<std::string>& sensitivity) {
    std::vector<std::string> columns, warnings;
    std::vector<double> values;  // rows x columns, row-major
    translate(path_, [&] {
      Locked locked;
      // The model analysed: this one, or with derived parameters named for sensitivities made
      // base ones.
      std::unique_ptr<kc::CompiledModel> base;
      const kc::CompiledModel* m = model_.get();
      kc::require_driven(*m);
      // An input driver left without its table is the command line's usage error.
      {
        kc::Mechanism copy = m->mechanism();
        kc::apply_inputs(copy, {}, true);
      }
      // The checks cli/analyze.cpp makes before solving.
      if (steps < 0) throw kc::UsageError("--steps must be 0 or more");
      if (!std::isfinite(t0) || !std::isfinite(t1))
        throw kc::UsageError("--t0 and --t1 must be finite");
      check_span(t0, t1);
      refuse_spatial(forces ? "analyze(forces=True)" : nullptr);
      kc::SensitivityModel sens;
      kc::AnalysisOptions options;
      std::unique_ptr<kc::ForceModel> force_model;
      std::vector<std::string> force_names;
      if (!sensitivity.empty()) {
        // Naming a derived parameter treats it as overridden, as on the command line.
        base = model_->with_base_parameters(sensitivity);
        if (base) m = base.get();
        sens = kc::build_sensitivity(*m, sensitivity);
        options.sensitivity = &sens;
      }
      if (forces) {
        force_model = std::make_unique<kc::ForceModel>(kc::forces_for_analysis(*m, t0));
        force_names = kc::force_columns(m->mechanism());
        options.forces = force_model.get();
      }
      options.warn = [&](const std::string& w) { warnings.push_back(one_line(w)); };
      // The command line's lines (analysis_rows.hpp), read back; a suspension's design position
      // is solved here, before any row.
      kc::AnalysisRows rows(*m, options, steps + 1LL, "analyze");
      std::string header = rows.header(force_names, sens.names);
      header.pop_back();
      columns = split(header);
      // The rows are kept (unlike the command line's, which stream): bounded as tolerance's.
      kc::require_kept_rows("analyze", steps + 1LL, columns.size());
      const auto keep = [&](std::string line) {
        line.pop_back();
        for (const auto& item : split(line)) values.push_back(std::strtod(item.c_str(), nullptr));
      };
      kc::run_analysis(
          *m, {t0, t1, steps}, [&](const kc::StateRow& row) { rows.take(row, keep); }, options);
      rows.finish(keep);
    });
    warn_all(warnings);
    py::dict out;
    const std::size_t n = columns.size(), rows = n ? values.size() / n : 0;
    for (std::size_t c = 0; c < n; ++c) {
      py::array_t<double> a(static_cast<py::ssize_t>(rows));
      double* d = a.mutable_data();
      for (std::size_t r = 0; r < rows; ++r) d[r] = values[r * n + c];
      out[py::str(columns[c])] = a;
    }
    return out;
  }

  // Phi, Phi_q, nu and gamma at (q, qd, t), as `kinegen eval` computes them.
  py::dict eval(std::optional<std::vector<double>> q_arg, std::optional<std::vector<double>> qd_arg,
                double t) {
    const int nq = nq_, nc = nc_;
    const auto vector = [&](const std::optional<std::vector<double>>& v, const char* name,
                            const Eigen::VectorXd& fallback) -> Eigen::VectorXd {
      if (!v) return fallback;
      if (static_cast<int>(v->size()) != nq)
        throw kc::UsageError(std::string(name) + " expects " + std::to_string(nq) +
                             " values (one per coordinate), got " + std::to_string(v->size()));
      return Eigen::Map<const Eigen::VectorXd>(v->data(), nq);
    };
    kc::EvalResult e;
    translate(path_, [&] {
      Locked locked;
      const Eigen::VectorXd q = vector(q_arg, "q", model_->q0());
      const Eigen::VectorXd qd = vector(qd_arg, "qd", Eigen::VectorXd::Zero(nq));
      e = kc::evaluate(*model_, q, qd, t);
    });
    {
      py::array_t<double> j({nc, nq});
      for (int r = 0; r < nc; ++r)
        for (int c = 0; c < nq; ++c) j.mutable_at(r, c) = e.phi_q(r, c);
      py::dict out;
      out["phi"] = to_numpy(e.phi);
      out["phi_q"] = j;
      out["nu"] = to_numpy(e.nu);
      out["gamma"] = to_numpy(e.gamma);
      // Outputs' values, as `kinegen eval` adds them.
      if (e.outputs.size() > 0) out["outputs"] = to_numpy(e.outputs);
      return out;
    }
  }

  // `kinegen check`: one dict per block and method; raises AnalysisError (the command line's
  // exit 1) when a block is beyond its bound.
  py::list check(int samples, unsigned seed, double t, double turns, int digits) {
    std::vector<kc::CheckRow> rows;
    translate(path_, [&] {
      Locked locked;
      if (samples < 1) throw kc::UsageError("--samples must be at least 1");
      kc::CheckOptions options;
      options.samples = samples;
      options.seed = seed;
      options.t = t;
      options.turns = turns;
      options.digits = digits;
      rows = kc::check_derivatives(*model_, options);
      for (const auto& r : rows)
        if (!r.ok())
          throw kc::AnalysisError(path_ +
                                  ": check: the symbolic derivatives differ from the numeric "
                                  "ones beyond their bounds");
    });
    py::list out;
    for (const auto& r : rows) {
      py::dict d;
      d["block"] = r.block;
      d["method"] = r.method;
      d["max_abs"] = r.max_abs;
      d["max_rel"] = r.max_rel;
      d["bound"] = r.bound;
      d["ok"] = r.ok();
      out.append(d);
    }
    return out;
  }

  // `kinegen generate`: writes DIR/<name>.hpp (through a temporary file) and returns its path.
  std::string generate(const std::string& dir, bool fold_params) {
    return translate(path_, [&] {
      Locked locked;
      std::unique_ptr<kc::CompiledModel> folded;
      if (fold_params) {
        kc::BuildOptions build;
        build.fold_params = true;
        build.inputs = build_.inputs;
        folded = kc::CompiledModel::from_file(path_, overrides_, build);
      }
      const kc::CompiledModel& m = folded ? *folded : *model_;
      const std::string text = kc::emit_header(m);
      std::error_code ec;
      fs::create_directories(dir, ec);
      const fs::path target = fs::path(dir) / (m.mechanism().name + ".hpp");
      fs::path temp = target;
      temp += ".tmp-kinegen-" + std::to_string(::getpid());
      {
        std::ofstream out(temp, std::ios::binary | std::ios::trunc);
        out << text;
        if (!out) {
          fs::remove(temp, ec);
          throw kc::UsageError("cannot write '" + target.string() + "'");
        }
      }
      fs::rename(temp, target, ec);
      if (ec) {
        fs::remove(temp, ec);
        throw kc::UsageError("cannot write '" + target.string() + "'");
      }
      return target.string();
    });
  }

  // `kinegen view`: the page of an analysis, a CSV or modes (view_page.cpp), written to path
  // unless it is empty; the command line's page, byte for byte.
  py::object view(const std::string& path, const kinegen::python::ViewArgs& args) {
    std::vector<std::string> warnings;
    std::string failure;
    std::string html = translate(path_, [&] {
      if (args.t0 && args.t1) check_span(*args.t0, *args.t1);
      refuse_spatial(!args.modes.empty() ? "view(modes=...)"
                                         : (args.forces ? "view(forces=True)" : nullptr));
      return kinegen::python::view_html(*model_, args, &warnings, &failure);
    });
    warn_all(warnings);
    py::object page =
        translate(path_, [&] { return kinegen::python::make_page(std::move(html), path); });
    if (!failure.empty()) {  // as the command line: the page of the rows so far, and exit 1
      PyErr_SetString(analysis_error.ptr(), python_names(one_line(failure)).c_str());
      throw py::error_already_set();
    }
    return page;
  }

  // Every coordinate, the bodies' x, y, phi and then the extra ones, as the CSV's
  // position columns name them.
  const std::vector<std::string>& coordinates() const { return coordinates_; }

  py::dict parameters() const {
    py::dict out;
    for (const auto& [name, value] : parameters_) out[py::str(name)] = value;
    return out;
  }

  // Forward dynamics and its linearization (dynamics_api.hpp), their errors turned
  // into the module's exceptions. Its methods take the library's lock themselves
  // around their library work, and build their Python results after it.
  template <class F>
  auto with_dynamics(const char* method, F&& f) {
    return translate(path_, [&] {
      refuse_spatial(method);
      if (!dynamics_) dynamics_ = std::make_unique<kinegen::python::DynamicsApi>(*model_);
      return f(*dynamics_);
    });
  }

  const std::string& name() const { return name_; }
  const std::string& path() const { return path_; }
  int nq() const { return nq_; }
  int nc() const { return nc_; }

 private:
  // What spatial files do not have yet (docs/format.md, Spatial mechanisms): dynamics, modes,
  // equilibria and forces.
  // InputError, as the command line's refusal of a spatial file.
  void refuse_spatial(const char* method) const {
    if (!spatial_ || !method) return;
    throw kc::InputError(path_, "space", space_loc_,
                         std::string("spatial files (space: 3d) are not supported by "
                                     "Mechanism.") +
                             method + " yet");
  }

  std::string path_;
  std::vector<kc::ParamOverride> overrides_;
  kc::BuildOptions build_;
  std::unique_ptr<kc::CompiledModel> model_;  // touched only under the library's lock
  std::unique_ptr<kinegen::python::DynamicsApi> dynamics_;  // the same
  std::string name_;
  int nq_ = 0, nc_ = 0;
  bool spatial_ = false;
  kc::SourceLoc space_loc_;
  std::vector<std::string> coordinates_;
  std::vector<std::pair<std::string, double>> parameters_;
};

}  // namespace

PYBIND11_MODULE(kinegen, m) {
  m.doc() =
      "kinegen: planar and spatial mechanism kinematics (the kinegen command line, in-process)";
  // Function-local statics that run Python code when first used (numpy's C API table imports
  // numpy, which may let another thread take the GIL) are made here, at import, where no other
  // thread can be inside this module: two threads' first calls would otherwise wait for each
  // other, one on the static's guard while holding the GIL, the other for the GIL.
  py::detail::npy_api::get();
  py::module_::import("warnings");
  kinegen::python::init_signal_checks();
  m.attr("__version__") = kc::kVersion;

  const py::handle error = PyErr_NewExceptionWithDoc(
      "kinegen.Error", "Base of kinegen's errors; str() is the command line's error: line",
      PyExc_Exception, nullptr);
  const auto derived = [&](const char* name, const char* doc, PyObject* builtin) {
    const py::tuple bases = py::make_tuple(error, py::handle(builtin));
    return py::handle(PyErr_NewExceptionWithDoc(name, doc, bases.ptr(), nullptr));
  };
  input_error = derived("kinegen.InputError",
                        "Invalid mechanism file or parameters (exit 2 on the command line)",
                        PyExc_ValueError);
  usage_error = derived("kinegen.UsageError", "Invalid arguments (exit 2 on the command line)",
                        PyExc_ValueError);
  analysis_error =
      derived("kinegen.AnalysisError",
              "The analysis failed: no assembly, singular Jacobian, no convergence (exit 1)",
              PyExc_RuntimeError);
  m.attr("Error") = error;
  m.attr("InputError") = input_error;
  m.attr("UsageError") = usage_error;
  m.attr("AnalysisError") = analysis_error;
  // For tests: how many tables the live Mechanism objects hold (equal tables count once).
  m.def("_live_tables", [] { return kc::live_tables(); });
  kinegen::python::bind_page(m);

  py::class_<Mechanism>(
      m, "Mechanism", R"doc(A mechanism file (format: docs/format.md), read and compiled in-process.

Mechanism(path, params={}, inputs={}) reads the YAML file; params overrides its parameters
(numbers or expression strings), inputs gives each input driver (f: input) its table
(name: CSV path). The methods run the command line's analyses with the same library calls,
so their numbers are the CSV's bit for bit:

  analyze(t0, t1, steps, forces=False, sensitivity=[])  columns -> numpy arrays
  eval(q=None, qd=None, t=0.0)                          Phi, Phi_q, nu, gamma
  check(samples=5, ...)                                 derivatives against numeric ones
  generate(dir='.', fold_params=False)                  writes DIR/<name>.hpp
  view(path='', t0=..., t1=..., steps=...)              the kinegen view page

The file's warnings (and an analysis's) are Python warnings (UserWarning); errors are
kinegen.InputError, kinegen.UsageError or kinegen.AnalysisError with the command line's
message.

  >>> m = kinegen.Mechanism('examples/four_bar.yaml', params={'omega': 2.0})
  >>> run = m.analyze(0, 3.14, 90)
  >>> run['rocker.phi'][:3])doc")
      .def(py::init<std::string, py::dict, py::dict>(), py::arg("path"),
           py::arg("params") = py::dict(), py::arg("inputs") = py::dict(),
           "Reads and compiles a mechanism file; params overrides parameters like --param "
           "(numbers or expression strings), inputs gives input drivers their tables like "
           "--input (name: CSV path).")
      .def(
          "analyze",
          [](Mechanism& mech, double t0, double t1, int steps, bool forces,
             const py::object& sensitivity) {
            return mech.analyze(t0, t1, steps, forces, names_of(sensitivity, "sensitivity"));
          },
          py::arg("t0"), py::arg("t1"), py::arg("steps"), py::arg("forces") = false,
          py::arg("sensitivity") = py::list(),
          "Position, velocity and acceleration at t_k = t0 + k (t1 - t0) / steps: a dict from "
          "the CSV's column names to numpy arrays, in the CSV's order; sensitivity=[p, ...] "
          "adds the d(C)/d(p) columns.")
      .def("eval", &Mechanism::eval, py::arg("q") = py::none(), py::arg("qd") = py::none(),
           py::arg("t") = 0.0,
           "Phi, Phi_q, nu and gamma at (q, qd, t) (q defaults to q0, qd to zeros).")
      .def("check", &Mechanism::check, py::arg("samples") = 5, py::arg("seed") = 1u,
           py::arg("t") = 0.0, py::arg("turns") = 0.0, py::arg("digits") = 40,
           "Symbolic derivatives against numeric ones, one dict per block and method.")
      .def("generate", &Mechanism::generate, py::arg("dir") = ".", py::arg("fold_params") = false,
           "Writes DIR/<name>.hpp and returns its path.")
      .def(
          "view",
          [](Mechanism& mech, const std::string& path, std::optional<double> t0,
             std::optional<double> t1, std::optional<int> steps, const std::string& csv,
             const std::string& modes, bool forces, int max_rows, int width) {
            return mech.view(path, {t0, t1, steps, csv, modes, forces, max_rows, width});
          },
          py::arg("path") = "", py::kw_only(), py::arg("t0") = py::none(),
          py::arg("t1") = py::none(), py::arg("steps") = py::none(), py::arg("csv") = "",
          py::arg("modes") = "", py::arg("forces") = false, py::arg("max_rows") = 200000,
          py::arg("width") = 800,
          "The page of kinegen view (an analysis t0, t1, steps; csv=RUN.csv; or modes=FILE.json) "
          "as a kinegen.Page, written to path if given; Jupyter shows it inline.")
      .def(
          "simulate",
          [](Mechanism& mech, double t1, int steps, double rtol, std::optional<double> atol,
             const std::string& method, double t0, const std::string& integrator, bool forces,
             bool allow_drift) {
            kinegen::python::SimulateArgs a{t0,     t1,         steps,  rtol,       atol,
                                            method, integrator, forces, allow_drift};
            std::vector<std::string> warnings;
            py::dict rows = mech.with_dynamics("simulate", [&](auto& d) {
              check_span(t0, t1);
              return d.simulate(a, warnings);
            });
            warn_all(warnings);
            return rows;
          },
          py::arg("t1"), py::arg("steps"), py::kw_only(), py::arg("rtol") = 1e-8,
          py::arg("atol") = py::none(), py::arg("method") = "minimal", py::arg("t0") = 0.0,
          py::arg("integrator") = "auto", py::arg("forces") = false, py::arg("allow_drift") = false,
          "Forward dynamics (kinegen simulate): rows at t0 + k (t1 - t0) / steps, a dict from "
          "simulate's CSV column names to numpy arrays, in the CSV's order. atol defaults to "
          "1e-2 rtol; allow_drift: an energy balance past its bound warns instead of raising.")
      .def(
          "dynamics",
          [](Mechanism& mech, double t, const std::vector<double>& z, const std::vector<double>& zd,
             kinegen::python::OptionalValues u) {
            return mech.with_dynamics("dynamics", [&](auto& d) { return d.dynamics(t, z, zd, u); });
          },
          py::arg("t"), py::arg("z"), py::arg("zd"), py::arg("u") = py::none(),
          "zdd at (t, z, zd, u): the free coordinates' accelerations under the forces, u the "
          "run-time inputs (Mechanism.inputs; default zeros). x' = (zd, zdd) is what "
          "linearize linearizes.")
      .def(
          "equilibrium",
          [](Mechanism& mech, double t, kinegen::python::OptionalValues u,
             kinegen::python::OptionalValues start, bool nearest) {
            return mech.with_dynamics("equilibrium",
                                      [&](auto& d) { return d.equilibrium(t, u, start, nearest); });
          },
          py::kw_only(), py::arg("t") = 0.0, py::arg("u") = py::none(),
          py::arg("start") = py::none(), py::arg("nearest") = false,
          "kinegen equilibrium: where the overdamped release from start (the free coordinates; "
          "default value0) comes to rest, or with nearest=True Newton's nearest root of "
          "B^T Q^A = 0 from it (kinegen equilibrium --from, --nearest); a dict with z, q, the "
          "reactions (forces), M_z, K_z, the stability and its directions.")
      .def(
          "modes",
          [](Mechanism& mech, double t, kinegen::python::OptionalValues z,
             kinegen::python::OptionalValues u) {
            return mech.with_dynamics("modes", [&](auto& d) { return d.modes(t, z, u); });
          },
          py::kw_only(), py::arg("t") = 0.0, py::arg("z") = py::none(), py::arg("u") = py::none(),
          "kinegen modes: about the equilibrium (or z), M_z, K_z, C_z, the frequencies (Hz), "
          "damping ratios and shapes (one row of dq per mode).")
      .def(
          "linearize",
          [](Mechanism& mech, double t, kinegen::python::OptionalValues z,
             kinegen::python::OptionalValues zd, kinegen::python::OptionalValues u) {
            return mech.with_dynamics("linearize",
                                      [&](auto& d) { return d.linearize(t, z, zd, u); });
          },
          py::kw_only(), py::arg("t") = 0.0, py::arg("z") = py::none(), py::arg("zd") = py::none(),
          py::arg("u") = py::none(),
          "kinegen linearize: the exact A and B of x' = f(x, u), x = (z, zd), at the point "
          "(defaults value0, v0, zeros), as a dict of numpy arrays with the names of x and u.")
      .def_property_readonly(
          "free",
          [](Mechanism& mech) {
            return mech.with_dynamics(nullptr, [](auto& d) { return d.free_names(); });
          },
          "Names of the free coordinates z, in order.")
      .def_property_readonly(
          "inputs",
          [](Mechanism& mech) {
            return mech.with_dynamics(nullptr, [](auto& d) { return d.input_names(); });
          },
          "Names of the run-time inputs u (f: input drivers' D, D_v, D_a; loads' inputs), in "
          "order.")
      .def_property_readonly(
          "coordinates", &Mechanism::coordinates,
          "Names of the coordinates q, in order (body.x, body.y, body.phi; in a spatial "
          "file body.x, body.y, body.z, body.e0 .. body.e3).")
      .def_property_readonly("parameters", &Mechanism::parameters,
                             "Parameter values after the overrides, in file order.")
      .def_property_readonly("name", &Mechanism::name, "The file's name: key.")
      .def_property_readonly("path", &Mechanism::path, "The mechanism file's path, as given.")
      .def_property_readonly("nq", &Mechanism::nq, "The number of coordinates q.")
      .def_property_readonly("nc", &Mechanism::nc, "The number of equations of Phi.")
      .def("__repr__", [](const Mechanism& mech) {
        return "<kinegen.Mechanism '" + mech.name() + "' from '" + mech.path() + "'>";
      });
}
