// Pictures of a mechanism: an SVG animation over an analysis (`kinegen animate`), or one still
// frame of it. Bodies are drawn through their joint and named points, joints as pins and
// slider blocks, ground as hatched pivots and guides, named points with their traced paths.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/constraints/registry.hpp"

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
  // Positions to draw instead of an analysis (one per frame, at the grid's times; a mode of
  // `kinegen animate --mode`), and the title that says what they are (default: the times).
  std::vector<Eigen::VectorXd> positions;
  std::string title;
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

// What animate draws, as numbers, for a renderer of its own (`kinegen view`'s page): the
// registry's Sketch completed over given positions (outlines through the joints and points,
// attachments inferred from the motion, the guides' travel) and the picture's pixel map.
struct AnimateDrawing {
  struct Guide : Sketch::Slider {
    double travel_min = 0, travel_max = 0;  // along dir, over the positions, with margins
  };
  std::vector<std::vector<Eigen::Vector2d>> bodies;  // outline points in each body's frame
  std::vector<Attach> pins, points;                  // points: Mechanism::points' order
  std::vector<Eigen::Vector2d> ground_pivots;
  std::vector<Guide> sliders, pitch_lines;
  std::vector<std::pair<Attach, Attach>> struts;
  std::vector<Sketch::Circle> pitch_circles;
  std::vector<Attach> welds;
  std::vector<Sketch::Curve> curves;
  // The loads (`forces:`). A spring_damper between its two points: a zig-zag where it is stiff,
  // a dashpot where it damps; a rotational one (rotational) a coil about a == b, the pin that
  // joins its bodies (else body j's origin).
  struct Spring {
    Attach a, b;
    bool spring = true, damper = false, rotational = false;
    std::string name;
  };
  std::vector<Spring> springs;
  // A force: an arrow of fixed length onto its point, along the force where it is constant,
  // else along the positive axis of each varying component (one arrow each). A torque: a curved
  // arrow about its body's origin, dir[0] > 0 counter-clockwise.
  struct Load {
    Attach at;
    Eigen::Vector2d dir = Eigen::Vector2d::UnitX();
    bool torque = false;
    std::string name;
  };
  std::vector<Load> loads;
  // The constraint that drew each pin, slider, strut, pitch circle, pitch line, weld, curve.
  std::vector<const Constraint*> pin_by, slider_by, strut_by, circle_by, line_by, weld_by, curve_by;
  // px = x0 + scale x, py = y0 - scale y; the picture's size, margin and title line (pixels).
  double scale = 1, x0 = 0, y0 = 0, width = 0, height = 0, margin = 0, title = 0;
  std::vector<std::pair<std::string, std::string>> colours;  // role ("link", ...), #rrggbb
};
// q: the positions (each nq long, at least one); width as AnimateOptions::width.
AnimateDrawing animate_drawing(const CompiledModel& model, std::vector<Eigen::VectorXd> q,
                               int width = 800);

}  // namespace kinegen::codegen
