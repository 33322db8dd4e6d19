// The pieces of `kinegen view`'s page that its files share (view_page.cpp, view_scene.cpp,
// view_space.cpp): a small JSON writer and the scene of the drawing.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/io/animate.hpp"

namespace kinegen::codegen::view {

// Appends JSON text. Strings are escaped for a <script> element too ('<' as \u003c), numbers
// have 17 significant digits (a double read back exactly); a number that is not finite is null.
class Json {
 public:
  Json& raw(const std::string& text) {
    out_ += text;
    return *this;
  }
  Json& key(const std::string& name);  // "name": (after a comma when needed)
  Json& string(const std::string& value);
  Json& number(double value);
  Json& vec(const Eigen::Vector2d& v);  // [x, y]
  Json& open(char bracket);             // { or [
  Json& close(char bracket);            // } or ]
  // Before a value in a list: a comma unless it is the first.
  Json& item();
  const std::string& text() const { return out_; }

 private:
  void separate();
  std::string out_;
  std::vector<bool> first_;  // per open bracket: nothing written in it yet
};

// Indices of the run's columns by name; -1 for a name it lacks.
class Columns {
 public:
  explicit Columns(const std::vector<std::string>& names) : names_(names) {}
  int find(const std::string& name) const;
  // The indices of base + suffix for each suffix the run has.
  std::vector<int> group(const std::string& base, const std::vector<const char*>& suffixes) const;

 private:
  const std::vector<std::string>& names_;
};

// The drawing as the page's scene: bodies, joints, guides, gears, curves, points and, where the
// run has their columns, reaction arrows; each element with its name and its columns.
void write_scene(Json& json, const CompiledModel& model, const AnimateDrawing& drawing,
                 const Columns& columns);

// A spatial file's scene (view_space.cpp): the bodies with their columns, every joint's and
// driver's type, bodies and vector keys (si, sj, axis_i, ...) evaluated, the named points and
// vectors; the page places each body from its 7 coordinates.
void write_space_scene(Json& json, const CompiledModel& model, const Columns& columns);
// The named points' offsets in their bodies, and a point of a body (or ground) at pose q.
std::vector<Eigen::Vector3d> space_point_offsets(const CompiledModel& model);
Eigen::Vector3d space_world(const Eigen::VectorXd& q, int body, const Eigen::Vector3d& s);

}  // namespace kinegen::codegen::view
