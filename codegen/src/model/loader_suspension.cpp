// Loader (loader.hpp): the `suspension:` block of a spatial file (docs/format.md, Suspension
// analysis). It names one corner's parts and appends their outputs to the file's own, written
// as expressions of the named points and vectors, so that their rates and accelerations are
// derived exactly like any output's.
#include <string>
#include <vector>

#include "loader.hpp"

namespace kinegen::codegen::model_detail {

namespace {

// The outputs' expressions, in the order docs/format.md lists them. P.x, V.x: the global
// components of a point or a vector (spatial outputs read them). The spin axis needs no
// normalization: every angle is an atan2 of a ratio, and the contact point divides by |V|.
std::vector<std::pair<std::string, std::string>> suspension_outputs(const Suspension& s) {
  const std::string w = s.wheel_center, v = s.spin_axis, u = s.steer_upper, l = s.steer_lower;
  const std::string sigma = s.sigma > 0 ? "" : "-";
  const std::string r = "(" + s.tire_radius.text + ")";
  const auto c = [](const std::string& p, const char* axis) { return p + "." + axis; };
  // h = |(V.x, V.y)|, n = |V|: the contact point is W + r (V.z V.xy, -h^2) / (n h).
  const std::string h = "sqrt(" + c(v, "x") + "^2+" + c(v, "y") + "^2)";
  const std::string n = "sqrt(" + c(v, "x") + "^2+" + c(v, "y") + "^2+" + c(v, "z") + "^2)";
  const std::string cx =
      "(" + c(w, "x") + "+" + r + "*" + c(v, "z") + "*" + c(v, "x") + "/(" + n + "*" + h + "))";
  const std::string cy =
      "(" + c(w, "y") + "+" + r + "*" + c(v, "z") + "*" + c(v, "y") + "/(" + n + "*" + h + "))";
  const std::string cz = "(" + c(w, "z") + "-" + r + "*" + h + "/" + n + ")";
  // G: the steer axis (L to U) where it meets the plane z = C_z.
  const std::string along =
      "((" + cz + "-" + c(l, "z") + ")/(" + c(u, "z") + "-" + c(l, "z") + "))";
  const auto g = [&](const char* axis) {
    return "(" + c(l, axis) + "+" + along + "*(" + c(u, axis) + "-" + c(l, axis) + "))";
  };
  const std::string kz = "(" + c(u, "z") + "-" + c(l, "z") + ")";
  return {
      {"toe", "atan2(" + c(v, "x") + "," + sigma + c(v, "y") + ")"},
      {"camber", "-atan2(" + c(v, "z") + "," + h + ")"},
      {"caster", "atan2(" + c(l, "x") + "-" + c(u, "x") + "," + kz + ")"},
      {"kpi", "atan2(" + std::string(s.sigma > 0 ? "" : "-") + "(" + c(l, "y") + "-" + c(u, "y") +
                  ")," + kz + ")"},
      {"contact_x", cx},
      {"contact_y", cy},
      {"contact_z", cz},
      {"scrub_radius", sigma + "(" + cy + "-" + g("y") + ")"},
      {"trail", g("x") + "-" + cx},
      {"wheel_travel", c(w, "z")},
      {"track_change", sigma + cy},
  };
}

}  // namespace

std::vector<int> Loader::read_springs(const YAML::Node& springs, const Mechanism& m) {
  const std::string item = "suspension";
  std::vector<int> out;
  if (!springs.IsSequence())
    fail(item + ".springs", loc_of(springs), "expected a list of output names");
  for (const YAML::Node& spring : springs) {
    const std::string sub = item + ".springs";
    if (!spring.IsScalar()) fail(sub, loc_of(spring), "expected the name of an output");
    int found = -1;
    for (std::size_t k = 0; k < m.outputs.size(); ++k)
      if (m.outputs[k].name == spring.Scalar()) found = static_cast<int>(k);
    // Spatial files have no spring_damper loads yet: a spring is an output giving its length.
    if (found < 0)
      fail(sub, loc_of(spring),
           "no output is named '" + spring.Scalar() +
               "' (a spring is an output giving its length, e.g. a distance between two "
               "points)");
    for (int k : out)
      if (k == found) fail(sub, loc_of(spring), "'" + spring.Scalar() + "' is listed twice");
    out.push_back(found);
  }
  return out;
}

void Loader::read_suspension(const YAML::Node& node, SourceLoc loc, Mechanism& m) {
  const std::string item = "suspension";
  if (!spatial_) fail(item, loc, "'suspension' belongs to spatial files (space: 3d)");
  if (!node.IsMap())
    fail(item, loc,
         "expected a mapping with side, upright, wheel_center, spin_axis, steer_axis and "
         "tire_radius");
  check_keys(node, item,
             {"side", "upright", "wheel_center", "spin_axis", "steer_axis", "tire_radius"},
             {"springs", "design_t"});
  Suspension s;
  s.loc = loc;
  const YAML::Node side = node["side"];
  const std::string side_text = side.IsScalar() ? side.Scalar() : "";
  if (side_text != "left" && side_text != "right")
    fail(item + ".side", loc_of(side), "side must be left (y > 0) or right");
  s.sigma = side_text == "left" ? 1 : -1;
  s.upright = body_ref(node["upright"], m, item + ".upright", false);
  const std::string upright = m.bodies[s.upright].name;
  // A point or a vector by name; on the upright when `on_upright`.
  const auto named = [&](const YAML::Node& key, const std::string& what,
                         const std::vector<Point>& list, bool on_upright) {
    const std::string sub = item + "." + what;
    if (!key.IsScalar()) fail(sub, loc_of(key), "expected the name of a point or vector");
    for (const Point& p : list)
      if (p.name == key.Scalar()) {
        if (on_upright && p.body != s.upright)
          fail(sub, loc_of(key),
               "'" + p.name + "' must be fixed in the upright '" + upright + "', not in '" +
                   (p.body == kGround ? std::string("ground") : m.bodies[p.body].name) + "'");
        return p.name;
      }
    fail(sub, loc_of(key),
         std::string("no ") + (&list == &m.points ? "point" : "vector") + " is named '" +
             key.Scalar() + "' (list it under " + (&list == &m.points ? "points:" : "vectors:") +
             ")");
  };
  s.wheel_center = named(node["wheel_center"], "wheel_center", m.points, true);
  s.spin_axis = named(node["spin_axis"], "spin_axis", m.vectors, true);
  const YAML::Node steer = node["steer_axis"];
  if (!steer.IsSequence() || steer.size() != 2)
    fail(item + ".steer_axis", loc_of(steer),
         "expected two point names [upper, lower] on the steering axis");
  s.steer_upper = named(steer[0], "steer_axis", m.points, false);
  s.steer_lower = named(steer[1], "steer_axis", m.points, false);
  if (s.steer_upper == s.steer_lower)
    fail(item + ".steer_axis", loc_of(steer), "the two points must differ");
  s.tire_radius = expr_of(node["tire_radius"], item + ".tire_radius");
  if (const YAML::Node t = node["design_t"]) s.design_t = expr_of(t, item + ".design_t");
  if (const YAML::Node springs = node["springs"]) s.springs = read_springs(springs, m);
  // The outputs share the names of the file's outputs, points, vectors, parameters and
  // definitions: a clash would make a column or an expression ambiguous.
  const auto outputs = suspension_outputs(s);
  for (const auto& output : outputs) {
    // Not a structured binding: clang before 16 cannot capture one in the lambda below.
    const std::string& name = output.first;
    const auto clash = [&](const auto& list) {
      for (const auto& x : list)
        if (x.name == name) return true;
      return false;
    };
    if (clash(m.outputs) || clash(m.points) || clash(m.vectors) || clash(m.parameters) ||
        clash(m.definitions) || m.find_body(name))
      fail(item, loc,
           "the suspension output '" + name +
               "' clashes with an output, a point, a vector, a parameter, a definition or a "
               "body of that name");
  }
  s.first_output = static_cast<int>(m.outputs.size());
  for (const auto& [name, text] : outputs) m.outputs.push_back({name, Expr{text, loc}, loc});
  m.suspension = std::move(s);
}

}  // namespace kinegen::codegen::model_detail
