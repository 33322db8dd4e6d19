// kinegen.Page and Mechanism.view's page (view_page.hpp).
#include "view_page.hpp"

#include <memory>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/io/output_file.hpp"
#include "kinegen/codegen/io/view.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "locked.hpp"

namespace py = pybind11;
namespace kc = kinegen::codegen;

namespace kinegen::python {

namespace {

struct Page {
  std::string html;
  std::string path;  // "" when not written

  // In an iframe's srcdoc: the attribute escapes & and " (and < > for old readers); sandboxed
  // with scripts only, so the page runs in an origin of its own.
  std::string repr_html() const {
    std::string escaped;
    escaped.reserve(html.size() + html.size() / 8);
    for (const char ch : html) {
      switch (ch) {
        case '&':
          escaped += "&amp;";
          break;
        case '"':
          escaped += "&quot;";
          break;
        case '<':
          escaped += "&lt;";
          break;
        case '>':
          escaped += "&gt;";
          break;
        default:
          escaped += ch;
      }
    }
    return "<iframe sandbox=\"allow-scripts\" style=\"width: 100%; height: 920px; border: 1px "
           "solid #ddd\" srcdoc=\"" +
           escaped + "\"></iframe>";
  }
};

void write(const std::string& path, const std::string& html) {
  Locked locked;  // the library's files (OutputFile), like all of it, under its lock
  kc::OutputFile out(path);
  out.stream() << html;
  out.commit();
}

}  // namespace

std::string view_html(const kc::CompiledModel& model, const ViewArgs& a,
                      std::vector<std::string>* warnings, std::string* failure) {
  Locked locked;
  // The command line's checks (cli/view.cpp), in its words.
  const bool grid = a.t0 || a.t1 || a.steps;
  if (static_cast<int>(!a.csv.empty()) + static_cast<int>(!a.modes.empty()) + grid != 1)
    throw kc::UsageError(
        "view shows one of: csv=RUN.csv, modes=MODES.json, or an analysis "
        "(t0, t1, steps)");
  if (grid && !(a.t0 && a.t1 && a.steps))
    throw kc::UsageError("an analysis to view needs t0, t1 and steps");
  if (a.forces && !grid) throw kc::UsageError("forces belongs to an analysis (t0, ...)");
  if (a.max_rows < 2) throw kc::UsageError("max_rows must be at least 2");
  if (grid && *a.steps < 0) throw kc::UsageError("--steps must be 0 or more");
  kc::require_viewer();
  if (grid) {
    // An analysis needs every coordinate driven: a free item (its motion is a simulation's) or
    // an input left without its table is refused, as `analyze` and the command line refuse it,
    // never drawn at 0.
    kc::require_driven(model);
    kc::Mechanism copy = model.mechanism();
    kc::apply_inputs(copy, {}, true);
  }
  kc::ViewOptions options;
  options.width = a.width;
  if (!a.modes.empty())
    return kc::view_modes_html(model, kc::read_modes_json(a.modes, model), options);
  const auto rows = static_cast<std::size_t>(a.max_rows);
  const kc::RunTable run =
      grid ? kc::analysis_table(
                 model, {*a.t0, *a.t1, *a.steps}, a.forces, rows,
                 [&](const std::string& w) { warnings->push_back(w); }, &options.failure)
           : kc::read_run_csv(a.csv, rows);
  *failure = options.failure;
  return kc::view_html(model, run, options);
}

py::object make_page(std::string html, const std::string& path) {
  if (!path.empty()) write(path, html);
  return py::cast(Page{std::move(html), path});
}

void bind_page(py::module_& m) {
  py::class_<Page>(m, "Page",
                   "The page of kinegen view: .html, .path (None if not written), .save(path); "
                   "Jupyter shows it inline")
      .def_property_readonly("html", [](const Page& p) { return p.html; })
      .def_property_readonly("path",
                             [](const Page& p) -> py::object {
                               if (p.path.empty()) return py::none();
                               return py::str(p.path);
                             })
      .def(
          "save",
          [](Page& p, const std::string& path) {
            write(path, p.html);
            p.path = path;
            return path;
          },
          py::arg("path"), "Writes the page to path (through a temporary file).")
      .def("_repr_html_", &Page::repr_html)
      .def(
          "show",
          [](const py::object& self) {
            // In IPython (Jupyter) the page shows inline; elsewhere in the web browser.
            try {
              if (!py::module_::import("IPython").attr("get_ipython")().is_none()) {
                py::module_::import("IPython.display").attr("display")(self);
                return;
              }
            } catch (const py::error_already_set&) {  // no IPython
            }
            Page& p = self.cast<Page&>();
            if (p.path.empty()) {
              const py::object tmp = py::module_::import("tempfile")
                                         .attr("mkstemp")(py::arg("suffix") = ".html",
                                                          py::arg("prefix") = "kinegen-view-");
              py::module_::import("os").attr("close")(tmp[py::int_(0)]);
              p.path = tmp[py::int_(1)].cast<std::string>();
              write(p.path, p.html);
            }
            const py::object absolute = py::module_::import("os.path").attr("abspath")(p.path);
            py::module_::import("webbrowser")
                .attr("open")("file://" + absolute.cast<std::string>());
          },
          "Shows the page: inline in Jupyter (IPython.display), else in the web browser.")
      .def("__repr__", [](const Page& p) {
        return "<kinegen.Page " + std::to_string(p.html.size() / 1024) + " KiB" +
               (p.path.empty() ? "" : " at '" + p.path + "'") + ">";
      });
}

}  // namespace kinegen::python
