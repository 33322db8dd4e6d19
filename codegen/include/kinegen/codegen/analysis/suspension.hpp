// What a `suspension:` block (docs/format.md, Suspension analysis) adds to an analysis beyond
// its outputs: wheel_travel and track_change measured from the design position, and a motion
// ratio column per spring.
#pragma once

#include <string>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"

namespace kinegen::codegen {

class SuspensionRows {
 public:
  // wheel_travel's and track_change's places among the suspension's outputs (after
  // Suspension::first_output), in the order loader_suspension.cpp appends them.
  static constexpr int kWheelTravel = 9, kTrackChange = 10;
  // Solves the design position (at design_t, from the q0 pose as the first solve of any
  // analysis does): AnalysisError if it fails. `options` as the run's (its warnings are not
  // repeated here).
  SuspensionRows(const CompiledModel& model, const AnalysisOptions& options);
  // The motion ratio columns' names (`<S>.motion_ratio`), after the outputs.
  static std::vector<std::string> columns(const Mechanism& m);
  // wheel_travel and track_change of a row, from the design position.
  void apply(StateRow& row) const;
  // Per row, each spring's -(dL/dt) / (d wheel_travel/dt); nan where |d wheel_travel/dt| is
  // at most 1e-9 of its largest value over `rows` (the run).
  std::vector<std::vector<double>> motion_ratios(const std::vector<StateRow>& rows) const;

 private:
  const Mechanism& m_;
  int travel_ = 0, track_ = 0;  // output indices
  double travel0_ = 0, track0_ = 0;
};

}  // namespace kinegen::codegen
