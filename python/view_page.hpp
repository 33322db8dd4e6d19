// kinegen.Page: the page of `kinegen view` in Python (Mechanism.view returns one), which
// Jupyter shows inline (_repr_html_: the page in a sandboxed iframe), and how Mechanism.view
// makes it: the same library calls as the command line, so the same bytes.
#pragma once

#include <pybind11/pybind11.h>

#include <optional>
#include <string>

#include "kinegen/codegen/compile/compiled_model.hpp"

namespace kinegen::python {

struct ViewArgs {
  std::optional<double> t0, t1;
  std::optional<int> steps;
  std::string csv, modes;
  bool forces = false;
  int max_rows = 200000;
  int width = 800;
};

// The page's text; the analysis' warnings in *warnings, a failure after some rows (the page
// then shows the rows before it) in *failure. Throws the library's errors (UsageError, ...).
// Runs its work without the GIL, under the library's lock (Locked).
std::string view_html(const codegen::CompiledModel& model, const ViewArgs& args,
                      std::vector<std::string>* warnings, std::string* failure);

// Writes `html` to `path` (through a temporary file) unless it is empty, and returns a Page.
pybind11::object make_page(std::string html, const std::string& path);

// Registers kinegen.Page.
void bind_page(pybind11::module_& m);

}  // namespace kinegen::python
