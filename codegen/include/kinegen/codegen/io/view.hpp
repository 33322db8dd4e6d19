// `kinegen view`: one self-contained HTML page of a run (a CSV of analyze, or of a simulation
// with the same position columns) or of a mechanism's vibration modes. The page draws the
// mechanism as `kinegen animate` does (animate_drawing: the registry's Sketch), with a time
// slider, play and pause, a speed control, uPlot plots of any columns chosen in the page and
// hover read-outs. Everything is inlined (uPlot from viewer/node_modules at build time, the
// run as base64 doubles): the page needs no server and makes no request.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"

namespace kinegen::codegen {

// A run as columns. Rows beyond a limit are decimated: every stride-th row and the last are
// kept, each with its values exactly as read (never averaged or interpolated).
struct RunTable {
  std::string source;  // the CSV's path, or what the page calls the run
  std::vector<std::string> columns;
  std::vector<std::vector<double>> values;  // values[column][row]
  std::size_t total_rows = 0;               // rows in the source
  std::size_t stride = 1;
  std::size_t rows() const { return values.empty() ? 0 : values[0].size(); }
};

// The rows kept of `total` when at most `max_rows` (>= 2) may be: every stride-th from the
// first, and the last.
std::size_t decimation_stride(std::size_t total, std::size_t max_rows);

// Reads a CSV with a header of names and rows of numbers (analyze's, or any with the same
// position columns). InputError (file, line) for an empty file, a header without rows, a
// repeated or empty name, a row of another length, a value that is not a number.
RunTable read_run_csv(const std::string& path, std::size_t max_rows);

// Runs the analysis (with the force columns when `forces`), keeping what the CSV of
// `kinegen analyze` would hold: the same columns, and values that read back from it exactly.
// An AnalysisError after some rows is returned in *failure (the rows so far kept); before any,
// it is thrown.
RunTable analysis_table(const CompiledModel& model, const TimeGrid& grid, bool forces,
                        std::size_t max_rows, const std::function<void(const std::string&)>& warn,
                        std::string* failure);

// Vibration modes about an equilibrium: q (one value per coordinate, coordinate_labels
// order), the frequencies (Hz) and for each a shape, dq per coordinate.
struct ModeSet {
  std::string source;
  Eigen::VectorXd q;
  std::vector<double> frequencies;
  std::vector<Eigen::VectorXd> shapes;
};

// Reads {"coordinates": [...] (optional, checked against the mechanism's), "q": [...],
// "frequencies": [...], "shapes": [[...], ...]}; InputError for anything else.
ModeSet read_modes_json(const std::string& path, const CompiledModel& model);

struct ViewOptions {
  int width = 800;                 // of the drawing, pixels (as animate's --width)
  std::string failure;             // shown in the page: why the run ends early
  std::vector<std::string> notes;  // shown in the page (warnings)
};

// Whether this build has the page (KINEGEN_BUILD_VIEWER); require_viewer throws UsageError
// saying how to build it when not, as view_html and view_modes_html do.
bool viewer_built();
void require_viewer();

// The page of a run. InputError when the run does not match the mechanism: a position column
// missing, or a named point's columns away from where the positions put it (another file or
// other parameters).
std::string view_html(const CompiledModel& model, const RunTable& run, const ViewOptions& options);
// The page of modes: each plays as an oscillation q + a sin(2 pi tau) dq.
std::string view_modes_html(const CompiledModel& model, const ModeSet& modes,
                            const ViewOptions& options);

}  // namespace kinegen::codegen
