// `kinegen animate`'s picture (animate.hpp): the Picture class, which solves the motion,
// collects what each constraint type draws (its Sketch), fits the view (animate.cpp) and writes
// the SVG (animate_svg.cpp). Private to the io stage.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <sstream>
#include <vector>

#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/kinematics.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/io/animate.hpp"

namespace kinegen::codegen::io_detail {

using Eigen::Vector2d;

// A block sliding on a guide (Sketch::Slider), with its travel along dir over the analysis.
struct Slider : Sketch::Slider {
  double travel_min = 0, travel_max = 0;
};

constexpr const char* kGroundColour = "#555555";
constexpr const char* kPinStroke = "#222222";
constexpr const char* kSliderFill = "#9ecae1";
constexpr const char* kPointColour = "#d62728";
constexpr const char* kPathColour = "#ff7f0e";
constexpr const char* kGearColour = "#2ca02c";
constexpr const char* kSpringColour = "#8c564b";
constexpr const char* kLoadColour = "#9467bd";
constexpr double kPi = 3.14159265358979323846;

inline Vector2d rotate(double phi, const Vector2d& s) {
  const double c = std::cos(phi), sn = std::sin(phi);
  return {c * s[0] - sn * s[1], sn * s[0] + c * s[1]};
}

inline Vector2d world(const Eigen::VectorXd& q, int body, const Vector2d& s) {
  if (body == kGround) return s;
  const double phi = q[3 * body + 2];
  const auto r = point_position(&q[3 * body], std::cos(phi), std::sin(phi), s[0], s[1]);
  return {r[0], r[1]};
}

inline Vector2d local(const Eigen::VectorXd& q, int body, const Vector2d& r) {
  if (body == kGround) return r;
  return rotate(-q[3 * body + 2], r - q.segment<2>(3 * body));
}

inline std::string num(double v) { return format_number(v, NumberStyle::kPixels); }

inline std::string escape(const std::string& text) {
  std::string out;
  for (char ch : text) {
    switch (ch) {
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '&':
        out += "&amp;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += ch;
    }
  }
  return out;
}

inline void add_unique(std::vector<Vector2d>& points, const Vector2d& p, double tol) {
  for (const auto& x : points)
    if ((x - p).norm() <= tol) return;
  points.push_back(p);
}

// The loads' symbols in pixels (y down), each a list of strokes (polylines); drawing.js draws
// the same. A spring-damper from a to b: the first stroke starts at a, the last ends at b.
using Strokes = std::vector<std::vector<Vector2d>>;
Strokes spring_strokes(const Vector2d& a, const Vector2d& b, bool spring, bool damper);
Strokes coil_strokes(const Vector2d& centre);
// A force's arrow onto `at`, along `dir` (world: y up).
Strokes force_strokes(const Vector2d& at, const Vector2d& dir);
// A torque's curved arrow about `centre`, counter-clockwise for sign > 0.
Strokes torque_strokes(const Vector2d& centre, double sign);
// SVG path data: "M x,y L x,y ..." per stroke.
std::string path_data(const Strokes& strokes);

// A single-point body's disc (pixels): a body drawn at one place is seen around its pin.
constexpr double kBodyDiscRadius = 11;
// The picture is at most this part of its width tall (the page beside its controls).
constexpr double kMaxAspect = 0.75;

class Picture {
 public:
  Picture(const CompiledModel& model, const AnimateOptions& options)
      : model_(model), options_(options) {}
  // Over given positions (kinegen view), for drawing() rather than render().
  Picture(const CompiledModel& model, std::vector<Eigen::VectorXd> q, int width)
      : model_(model), q_(std::move(q)) {
    options_.width = width;
  }
  // The drawing as numbers (animate_drawing.cpp).
  AnimateDrawing drawing();
  std::string render() {
    solve();
    collect();
    infer_attachments();
    fit();
    return emit();
  }

 private:
  double number(const Expr& e, const std::string& item) const {
    return model_.geometry_number(e, item);
  }
  void solve();
  // Where each joint's J.fx, J.fy act (the body and point columns_from_lambda reports) and
  // their column in the force columns: after the drivers' efforts, three per joint.
  void collect_reactions();
  void collect();
  // A curve key of `c` at u: the curve reads only its own coordinate (checked when
  // it was derived), so every extra coordinate is set to u.
  Vector2d curve_point(const Constraint& c, const std::string& key, double u) const;
  // Where to draw a curve in extra coordinate k: over its travel in the analysis with a
  // quarter of it as margin on either side; an angle (a cam's profile, a roller) a whole turn.
  std::pair<double, double> curve_range(int k) const;
  // A point that keeps its place in a body's frame over the whole analysis belongs to that
  // body's drawing, whichever body the file put it on: this draws mechanisms written with
  // `expression` constraints, where the joints are not named.
  void infer_attachments();
  // The loads of `forces:`: springs, dampers, forces and torques (AnimateDrawing's).
  void collect_loads();
  // Extents of everything drawn, over every frame; the world-to-pixel map from them.
  void fit();
  Vector2d px(const Vector2d& w) const { return {x0_ + scale_ * w[0], y0_ - scale_ * w[1]}; }
  bool still() const { return options_.frame >= 0; }
  int frames() const { return static_cast<int>(q_.size()); }
  // An attribute that changes from frame to frame: its value now, or an <animate> element.
  struct Animated {
    std::string name;
    std::function<std::string(int)> at;
  };
  void element(std::ostringstream& os, const std::string& tag, const std::string& fixed,
               const std::vector<Animated>& animated, const std::string& content = "");
  std::string points_at(int f, const std::function<std::vector<Vector2d>(int)>& shape) const;
  std::string emit();
  // Traced paths of the named points (the whole analysis, also in a still frame).
  void draw_paths(std::ostringstream& os);
  // Guides: fixed ones once; those on moving bodies (slots) move with them.
  void draw_guides(std::ostringstream& os);
  // Ground pivots: a triangle with hatching under the pin.
  void draw_ground_pivots(std::ostringstream& os);
  // Struts of distance constraints.
  void draw_struts(std::ostringstream& os);
  // Bodies: a bar through two points, a plate through more.
  void draw_bodies(std::ostringstream& os);
  // Pitch circles of gears and pinions, each with a radius along its body's x axis that
  // shows its rotation; the racks' pitch lines (dash-dot, as in a drawing).
  void draw_gears(std::ostringstream& os);
  // Slot curves and cam profiles, sampled in their bodies' frames.
  void draw_curves(std::ostringstream& os);
  // Slider blocks, along their guide.
  void draw_sliders(std::ostringstream& os);
  // Pins of revolute joints.
  void draw_pins(std::ostringstream& os);
  // Welds of fixed joints: a filled square where the bodies are joined.
  void draw_welds(std::ostringstream& os);
  // Reaction forces: an arrow from each joint's point, to one scale for the whole picture.
  void draw_reactions(std::ostringstream& os);
  // Named points and their labels.
  void draw_points(std::ostringstream& os);
  // Springs and dampers (zig-zags, dashpots, coils).
  void draw_springs(std::ostringstream& os);
  // Applied forces and torques: arrows of fixed length.
  void draw_loads(std::ostringstream& os);
  // The title's width in pixels, about (14 px sans-serif).
  std::size_t title_chars() const;
  static constexpr double kMargin = 40;  // pixels around the extents (ground marks, labels)
  static constexpr double kTitle = 24;   // pixels above for the title line
  const CompiledModel& model_;
  AnimateOptions options_;
  std::vector<Eigen::VectorXd> q_;
  std::vector<double> t_;
  std::vector<std::vector<Vector2d>> body_points_;
  std::vector<Attach> pins_, named_;
  std::vector<Vector2d> ground_pivots_;
  std::vector<Slider> sliders_;
  std::vector<std::pair<Attach, Attach>> struts_;
  std::vector<Sketch::Circle> pitch_circles_;
  std::vector<Slider> pitch_lines_;  // travel: of the pinion's centre along the line
  std::vector<Attach> welds_;
  std::vector<Sketch::Curve> curves_;
  std::vector<AnimateDrawing::Spring> springs_;
  std::vector<AnimateDrawing::Load> loads_;
  // Each drawing constraint with the Sketch's element counts after it (AnimateDrawing's *_by).
  std::vector<std::pair<const Constraint*, std::array<std::size_t, 7>>> drawn_;
  // With options_.forces.
  struct Reaction {
    Attach at;
    int column;
    std::string item;
  };
  ForceModel force_model_;
  std::vector<std::vector<double>> forces_;
  std::vector<Reaction> reactions_;
  double largest_force_ = 0;
  double scale_ = 1, x0_ = 0, y0_ = 0, width_ = 0, height_ = 0, duration_ = 1;
};

}  // namespace kinegen::codegen::io_detail
