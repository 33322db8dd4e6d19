// Pictures of a mechanism: an SVG animation over an analysis (`kinegen animate`), or one still
// frame of it. Bodies are drawn through their joint and named points, joints as pins and
// slider blocks, ground as hatched pivots and guides, named points with their traced paths.
#pragma once

#include <functional>
#include <string>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/compiled_model.hpp"

namespace kinegen::codegen {

struct AnimateOptions {
  TimeGrid grid;
  int frame = -1;       // >= 0: a still picture of analysis row `frame` (no animation)
  int width = 800;      // pixels; the height follows from the extents (at most the width)
  double duration = 0;  // seconds per pass; 0: t1 - t0, or 4 s if that is not positive
  // Draws each joint's reaction force (analyze --forces: J.fx, J.fy on the body it reports) as
  // an arrow at its point, all to one scale: the largest over the analysis is a quarter of the
  // picture's smaller side.
  bool forces = false;
  // Receives the analysis' warnings (one line each, without "warning: "); none if empty.
  std::function<void(const std::string&)> warn;
};

// The colours a test (or a user's stylesheet) can rely on.
inline constexpr const char* kLinkColour = "#1f77b4";
inline constexpr const char* kBackgroundColour = "#ffffff";
inline constexpr const char* kForceColour = "#2ca02c";

// The SVG text. The root element carries the world-to-pixel map as
// data-kinegen-scale / -x0 / -y0: px = x0 + scale x, py = y0 - scale y (y up in the world).
// Throws AnalysisError if the analysis fails, UsageError for a bad frame or size (and with
// `forces`, forces_for_analysis' errors).
std::string animate_svg(const CompiledModel& model, const AnimateOptions& options);

}  // namespace kinegen::codegen
