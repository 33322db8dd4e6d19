// Loader (loader.hpp): what spatial files add (docs/format.md, Spatial mechanisms): `space`,
// the bodies' poses (r0 with rot0, p0 or q0), 3-vectors, `vectors:`, the drivers' `joint` key
// and the Euler parameter normalization rows.
#include <string>
#include <vector>

#include "loader.hpp"

namespace kinegen::codegen::model_detail {

void Loader::read_space(const YAML::Node& root, Mechanism& m) {
  if (const YAML::Node space = root["space"]) {
    const std::string text = space.IsScalar() ? space.Scalar() : "";
    if (text != "2d" && text != "3d")
      fail("space", loc_of(space), "space must be 2d (planar, the default) or 3d (spatial)");
    m.spatial = spatial_ = text == "3d";
    m.space_loc = loc_of(space);
  }
  if (!spatial_) {
    if (root["vectors"])
      fail("vectors", loc_of(root["vectors"]), "'vectors' belongs to spatial files (space: 3d)");
    return;
  }
  // Spatial dynamics and loads come later; their keys are refused, never ignored.
  for (const char* key : {"free", "forces", "gravity", "stop_when", "coordinates"})
    if (root[key])
      fail(key, loc_of(root[key]),
           std::string("'") + key + "' is not supported in spatial files (space: 3d) yet");
}

Vec2 Loader::vec_of(const YAML::Node& node, const std::string& item) {
  if (!spatial_) return vec2_of(node, item);
  if (!node.IsSequence() || node.size() != 3)
    fail(item, loc_of(node), "expected a vector of 3 numbers, e.g. [0, 0, 0] (space: 3d)");
  return Vec2{expr_of(node[0], item), expr_of(node[1], item), expr_of(node[2], item)};
}

void Loader::read_spatial_pose(const YAML::Node& b, const std::string& item, Body& body) {
  Body::Pose& pose = body.pose;
  const Expr zero{"0", body.loc};
  pose.r0 = {zero, zero, zero};
  pose.axis = {Expr{"1", body.loc}, zero, zero};
  pose.angle = zero;
  pose.rotation_loc = body.loc;
  int given = 0;
  for (const char* key : {"q0", "p0", "rot0"}) given += b[key] ? 1 : 0;
  if (given > 1) fail(item, body.loc, "give one of q0, p0 and rot0 (they all set the orientation)");
  const auto numbers = [&](const YAML::Node& node, std::size_t n, const std::string& what) {
    if (!node.IsSequence() || node.size() != n)
      fail(item, loc_of(node),
           what + " must be a vector of " + std::to_string(n) + " numbers" +
               (n == 7 ? " [x, y, z, e0, e1, e2, e3]" : ""));
    std::vector<Expr> out;
    for (std::size_t k = 0; k < n; ++k) out.push_back(expr_of(node[k], item + " " + what));
    return out;
  };
  if (const YAML::Node r0 = b["r0"]) {
    const auto v = numbers(r0, 3, "r0");
    pose.r0 = {v[0], v[1], v[2]};
  }
  if (const YAML::Node q0 = b["q0"]) {
    if (b["r0"]) fail(item, loc_of(q0), "give either q0 or r0 with p0 or rot0, not both");
    const auto v = numbers(q0, 7, "q0");
    pose.r0 = {v[0], v[1], v[2]};
    pose.p0.assign(v.begin() + 3, v.end());
    pose.rotation_loc = loc_of(q0);
  }
  if (const YAML::Node p0 = b["p0"]) {
    pose.p0 = numbers(p0, 4, "p0");
    pose.rotation_loc = loc_of(p0);
  }
  if (const YAML::Node rot0 = b["rot0"]) {
    if (!rot0.IsMap()) fail(item, loc_of(rot0), "rot0 must be {axis: [x, y, z], angle: A}");
    check_keys(rot0, item + " rot0", {"axis", "angle"}, {});
    const auto v = numbers(rot0["axis"], 3, "rot0 axis");
    pose.axis = {v[0], v[1], v[2]};
    pose.angle = expr_of(rot0["angle"], item + " rot0 angle");
    pose.rotation_loc = loc_of(rot0);
  }
}

void Loader::read_vectors(const YAML::Node& node, Mechanism& m) {
  if (node.IsNull()) return;
  if (!node.IsSequence()) fail("vectors", loc_of(node), "expected a list of vectors");
  for (std::size_t k = 0; k < node.size(); ++k) {
    const YAML::Node v = node[k];
    std::string item = "vectors[" + std::to_string(k) + "]";
    if (!v.IsMap()) fail(item, loc_of(v), "expected a mapping with 'name', 'body' and 'v'");
    check_keys(v, item, {"name", "body", "v"}, {});
    Point vector;
    vector.name = name_of(v["name"], item);
    item = "vector '" + vector.name + "'";
    vector.body = body_ref(v["body"], m, item, false);
    vector.s = vec_of(v["v"], item + " v");
    vector.loc = loc_of(v);
    for (const Point& p : m.points)
      if (p.name == vector.name) fail(item, vector.loc, "the name is a point's too");
    for (const Point& other : m.vectors)
      if (other.name == vector.name) fail(item, vector.loc, "duplicate vector name");
    m.vectors.push_back(std::move(vector));
  }
}

void Loader::add_normalization(Mechanism& m) {
  if (!spatial_) return;
  const ConstraintKind* kind = nullptr;
  for (const ConstraintKind* k : constraint_kinds())
    if (std::string(k->name) == "euler_parameters") kind = k;
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    Constraint c;
    c.kind = kind;
    c.name = "euler_" + m.bodies[b].name;
    c.item = c.name;
    c.loc = m.bodies[b].loc;
    c.i = static_cast<int>(b);
    m.normalization.push_back(std::move(c));
  }
}

int Loader::joint_ref(const YAML::Node& node, const Mechanism& m, const std::string& item) {
  if (!node.IsScalar()) fail(item, loc_of(node), "joint must be the name of a joint");
  for (std::size_t k = 0; k < m.joints.size(); ++k)
    if (m.joints[k].name == node.Scalar()) return static_cast<int>(k);
  fail(item, loc_of(node), "no joint is named '" + node.Scalar() + "' (give the joint a name:)");
}

}  // namespace kinegen::codegen::model_detail
