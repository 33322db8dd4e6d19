// The 3D scene of `kinegen view`'s page for a spatial file (docs/format.md, Spatial
// mechanisms): what the page needs to place every body from its 7 coordinates per row and draw
// it from its joints' points and axes, named points and named vectors. The page (space.js)
// draws with three.js; nothing here is drawn, only measured.
#include <cmath>

#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/symbolic/symbolic.hpp"
#include "view_json.hpp"

namespace kinegen::codegen::view {

namespace {

// How the page names a joint or driver: its name and its item ("bearing: joints[0] (revolute)").
std::string space_title(const Constraint& c) {
  return c.name.empty() ? c.item : c.name + ": " + c.item;
}

void space_vec(Json& json, const Eigen::Vector3d& v) {
  json.open('[').item().number(v[0]).item().number(v[1]).item().number(v[2]).close(']');
}

// A vector key of a joint, evaluated (its z absent in the text: 0).
Eigen::Vector3d space_key(const CompiledModel& model, const Constraint& c, const Vec2& v) {
  const auto value = [&](const Expr& e) {
    return e.text.empty() ? 0.0 : model.geometry_number(e, c.item);
  };
  return {value(v.x), value(v.y), value(v.z)};
}

Eigen::Vector3d space_number3(const CompiledModel& model, const std::vector<GiNaC::ex>& v) {
  const auto& s = model.symbolic();
  Eigen::Vector3d out;
  for (int k = 0; k < 3; ++k)
    out[k] = to_double(substitute_params(v[k], model.symbols(), s.param_values));
  return out;
}

void space_constraint(Json& json, const CompiledModel& model, const Constraint& c) {
  json.item().open('{').key("name").string(space_title(c)).key("type").string(c.type_name());
  json.key("driver").raw(c.is_driver ? "true" : "false");
  json.key("i").raw(std::to_string(c.i)).key("j").raw(std::to_string(c.j));
  if (c.joint >= 0) json.key("joint").raw(std::to_string(c.joint));
  json.key("keys").open('{');
  for (const auto& [key, v] : c.vectors) {
    json.key(key);
    space_vec(json, space_key(model, c, v));
  }
  json.close('}').close('}');
}

}  // namespace

std::vector<Eigen::Vector3d> space_point_offsets(const CompiledModel& model) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : model.symbolic().point_s3) out.push_back(space_number3(model, p));
  return out;
}

Eigen::Vector3d space_world(const Eigen::VectorXd& q, int body, const Eigen::Vector3d& s) {
  if (body == kGround) return s;
  const Eigen::Vector3d r = q.segment<3>(7 * body);
  const double e0 = q[7 * body + 3];
  const Eigen::Vector3d e = q.segment<3>(7 * body + 4);
  // A(p) s in the homogeneous form of docs/format.md, Spatial mechanisms.
  return r + (e0 * e0 - e.squaredNorm()) * s + 2 * e * e.dot(s) + 2 * e0 * e.cross(s);
}

void write_space_scene(Json& json, const CompiledModel& model, const Columns& columns) {
  const Mechanism& m = model.mechanism();
  json.key("length_scale").number(model.symbolic().length_scale).key("bodies").open('[');
  for (const auto& b : m.bodies) {
    json.item().open('{').key("name").string(b.name).key("columns").open('[');
    for (int c : columns.group(b.name, {".x", ".y", ".z", ".e0", ".e1", ".e2", ".e3", ".vx", ".vy",
                                        ".vz", ".wx", ".wy", ".wz"}))
      json.item().raw(std::to_string(c));
    json.close(']').close('}');
  }
  json.close(']').key("joints").open('[');
  for (const Constraint& c : m.joints) space_constraint(json, model, c);
  json.close(']').key("drivers").open('[');
  for (const Constraint& c : m.drivers) space_constraint(json, model, c);
  json.close(']').key("points").open('[');
  const auto offsets = space_point_offsets(model);
  for (std::size_t k = 0; k < m.points.size(); ++k) {
    json.item().open('{').key("name").string(m.points[k].name);
    json.key("body").raw(std::to_string(m.points[k].body)).key("s");
    space_vec(json, offsets[k]);
    json.key("columns").open('[');
    for (int c : columns.group(m.points[k].name, {".x", ".y", ".z", ".vx", ".vy", ".vz"}))
      json.item().raw(std::to_string(c));
    json.close(']').close('}');
  }
  json.close(']').key("vectors").open('[');
  for (std::size_t k = 0; k < m.vectors.size(); ++k) {
    json.item().open('{').key("name").string(m.vectors[k].name);
    json.key("body").raw(std::to_string(m.vectors[k].body)).key("v");
    space_vec(json, space_number3(model, model.symbolic().vectors3[k]));
    json.key("columns").open('[');
    for (int c : columns.group(m.vectors[k].name, {".x", ".y", ".z"}))
      json.item().raw(std::to_string(c));
    json.close(']').close('}');
  }
  json.close(']');
}

}  // namespace kinegen::codegen::view
