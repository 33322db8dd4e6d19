// The rows of an analysis as its CSV holds them, made in one place for every consumer: `kinegen
// analyze`, the analysis `kinegen view` runs for its page and the Python module's analyze.
// Spatial files' rows carry their angular rates, points and vectors in 3D; a `suspension:`
// block's wheel_travel and track_change are measured from the design position and its motion
// ratio columns added (docs/format.md, Suspension analysis), which needs the whole run: such
// rows are kept until finish().
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"

namespace kinegen::codegen {

class SpatialAnalysis;
class SuspensionRows;

class AnalysisRows {
 public:
  // `options`: the run's (its solver choice solves a suspension's design position, here: an
  // AnalysisError or InputError if that fails). `rows`: how many the run has, which bounds
  // what a suspension keeps (require_kept_rows, naming `what`).
  AnalysisRows(const CompiledModel& model, const AnalysisOptions& options, long long rows,
               const std::string& what);
  ~AnalysisRows();
  AnalysisRows(const AnalysisRows&) = delete;
  AnalysisRows& operator=(const AnalysisRows&) = delete;

  // csv_header's line, the motion ratio columns after the forces' and before the
  // sensitivities; with its line break.
  std::string header(std::vector<std::string> forces,
                     const std::vector<std::string>& sensitivity) const;
  // Each line of the CSV, with its line break.
  using LineSink = std::function<void(const std::string&)>;
  // A solved row: its line goes to `line` now, or at finish() for a suspension.
  void take(const StateRow& row, const LineSink& line);
  // The kept rows' lines (those solved so far when the run failed).
  void finish(const LineSink& line);

 private:
  std::string text(const StateRow& row, const std::vector<double>& extra) const;

  const CompiledModel& model_;
  std::unique_ptr<SpatialAnalysis> spatial_;
  std::unique_ptr<SuspensionRows> suspension_;
  std::vector<StateRow> kept_;
};

}  // namespace kinegen::codegen
