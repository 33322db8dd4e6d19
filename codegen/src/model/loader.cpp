// Loader (loader.hpp): the file, its names and expressions, bodies, coordinates, points and
// outputs, and the check that names are unique.
#include "loader.hpp"

#include <algorithm>
#include <cctype>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_set>
#include <vector>

#include "kinegen/codegen/symbolic/functions.hpp"

namespace kinegen::codegen::model_detail {

namespace {

// Names the expression language gives a meaning of its own.
const std::unordered_set<std::string>& reserved_names() {
  static const std::unordered_set<std::string> kReserved = [] {
    std::unordered_set<std::string> names = {"ground", "t",     "pi",      "Pi",
                                             "I",      "Euler", "Catalan", "pow"};
    for (const MathFunction& f : kMathFunctions) names.insert(f.name);
    return names;
  }();
  return kReserved;
}

}  // namespace

SourceLoc loc_of(const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  if (mark.line < 0) return {};
  return {mark.line + 1, mark.column + 1};
}

Mechanism Loader::load(const YAML::Node& root) {
  if (!root.IsDefined() || root.IsNull()) fail("file", {}, "the file is empty");
  if (!root.IsMap()) fail("file", loc_of(root), "the top level must be a mapping of keys");
  check_keys(root, "file", {"name"},
             {"space", "parameters", "definitions", "bodies", "coordinates", "joints", "drivers",
              "points", "vectors", "outputs", "gravity", "forces", "free", "stop_when",
              "suspension"});
  Mechanism m;
  m.source = source_;
  read_space(root, m);
  m.name = name_of(root["name"], "name");
  m.name_loc = loc_of(root["name"]);
  if (root["parameters"]) read_named(root["parameters"], "parameters", "value", m.parameters);
  if (root["definitions"])
    read_named(root["definitions"], "definitions", "expression", m.definitions);
  if (!root["bodies"]) fail("file", loc_of(root), "missing key 'bodies' (the moving bodies)");
  read_bodies(root["bodies"], m);
  if (root["coordinates"]) read_coordinates(root["coordinates"], m);
  read_constraints(root["joints"], "joints", false, m);
  read_constraints(root["drivers"], "drivers", true, m);
  if (root["points"]) read_points(root["points"], m);
  if (root["vectors"]) read_vectors(root["vectors"], m);
  add_normalization(m);
  if (root["outputs"]) read_outputs(root["outputs"], m);
  for (auto it = root.begin(); it != root.end(); ++it)
    if (it->first.Scalar() == "suspension") read_suspension(it->second, loc_of(it->first), m);
  if (root["gravity"]) {
    m.forces.gravity = vec2_of(root["gravity"], "gravity");
    m.forces.gravity_loc = loc_of(root["gravity"]);
  }
  if (root["forces"]) read_forces(root["forces"], m);
  read_constraints(root["free"], "free", true, m);
  if (root["stop_when"]) m.stop_when = expr_of(root["stop_when"], "stop_when");
  check_unique_names(m);
  return m;
}

// Every key must be known (catches misspellings) and appear once.
void Loader::check_keys(const YAML::Node& map, const std::string& item,
                        const std::vector<std::string>& required,
                        const std::vector<std::string>& optional) {
  std::set<std::string> seen;
  for (auto it = map.begin(); it != map.end(); ++it) {
    if (!it->first.IsScalar()) fail(item, loc_of(it->first), "keys must be plain names");
    const std::string key = it->first.Scalar();
    if (!seen.insert(key).second) fail(item, loc_of(it->first), "duplicate key '" + key + "'");
    const bool known = std::find(required.begin(), required.end(), key) != required.end() ||
                       std::find(optional.begin(), optional.end(), key) != optional.end();
    if (!known) {
      std::string allowed;
      for (const auto& k : required) allowed += (allowed.empty() ? "" : ", ") + k;
      for (const auto& k : optional) allowed += (allowed.empty() ? "" : ", ") + k;
      fail(item, loc_of(it->first), "unknown key '" + key + "' (expected: " + allowed + ")");
    }
  }
  for (const auto& k : required)
    if (!seen.count(k)) fail(item, loc_of(map), "missing key '" + k + "'");
}

std::string Loader::name_of(const YAML::Node& node, const std::string& item) {
  if (!node.IsScalar()) fail(item, loc_of(node), "a name must be a plain string");
  const std::string name = node.Scalar();
  if (name.size() > kMaxNameLength)
    fail(item, loc_of(node),
         "the name is " + std::to_string(name.size()) + " characters long; a name has at most " +
             std::to_string(kMaxNameLength));
  if (!is_valid_identifier(name))
    fail(item, loc_of(node),
         "'" + name +
             "' is not a valid name (a C identifier that is not a C++ keyword and does not "
             "start with '_' or contain '__')");
  if (reserved_names().count(name))
    fail(item, loc_of(node), "'" + name + "' is reserved in expressions");
  return name;
}

Expr Loader::expr_of(const YAML::Node& node, const std::string& item) {
  if (!node.IsScalar() || node.Scalar().empty())
    fail(item, loc_of(node), "expected a number or an expression string");
  const std::string& text = node.Scalar();
  // YAML's special floats (.nan, .inf, -.Inf, ...) are numbers to YAML but not to kinegen.
  std::string bare = text.substr(text[0] == '+' || text[0] == '-' ? 1 : 0);
  for (char& ch : bare) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (bare == ".nan" || bare == ".inf")
    fail(item, loc_of(node), "'" + text + "' is not a finite number");
  // Bounds that keep the symbolic stage fast and its recursion shallow on hostile input;
  // real mechanisms are far inside them.
  if (text.size() > kMaxExpressionLength)
    fail(item, loc_of(node),
         "the expression is longer than " + std::to_string(kMaxExpressionLength) + " characters");
  int depth = 0, deepest = 0;
  for (char ch : text) {
    depth += ch == '(' ? 1 : (ch == ')' ? -1 : 0);
    deepest = std::max(deepest, depth);
  }
  if (deepest > kMaxNesting)
    fail(item, loc_of(node),
         "the expression nests parentheses deeper than " + std::to_string(kMaxNesting));
  return Expr{text, loc_of(node)};
}

// YAML's true/false (and its other spellings: True, FALSE, yes, no, on, off).
bool Loader::flag_of(const YAML::Node& node, const std::string& item) {
  bool value = false;
  if (!node.IsScalar() || !YAML::convert<bool>::decode(node, value))
    fail(item, loc_of(node), "expected true or false");
  return value;
}

Vec2 Loader::vec2_of(const YAML::Node& node, const std::string& item) {
  if (!node.IsSequence() || node.size() != 2)
    fail(item, loc_of(node), "expected a vector of 2 numbers, e.g. [0, 0]");
  return Vec2{expr_of(node[0], item), expr_of(node[1], item)};
}

void Loader::read_outputs(const YAML::Node& node, Mechanism& m) {
  if (node.IsNull()) return;
  if (!node.IsMap()) fail("outputs", loc_of(node), "expected a mapping name: expression");
  std::set<std::string> seen;
  for (auto it = node.begin(); it != node.end(); ++it) {
    const std::string name = name_of(it->first, "outputs");
    const std::string item = "outputs." + name;
    if (!seen.insert(name).second) fail(item, loc_of(it->first), "duplicate output");
    m.outputs.push_back({name, expr_of(it->second, item), loc_of(it->first)});
  }
}

void Loader::read_bodies(const YAML::Node& node, Mechanism& m) {
  if (!node.IsSequence() || node.size() == 0)
    fail("bodies", loc_of(node), "expected a non-empty list of bodies");
  for (std::size_t k = 0; k < node.size(); ++k) {
    const YAML::Node b = node[k];
    std::string item = "bodies[" + std::to_string(k) + "]";
    if (!b.IsMap()) fail(item, loc_of(b), "expected a mapping with 'name' and 'q0'");
    if (spatial_) {
      check_keys(b, item, {"name"}, {"r0", "rot0", "p0", "q0"});
      Body body;
      body.name = name_of(b["name"], item);
      body.loc = loc_of(b);
      read_spatial_pose(b, "body '" + body.name + "'", body);
      m.forces.bodies.push_back({});
      if (m.find_body(body.name)) fail(item, loc_of(b["name"]), "duplicate body name");
      m.bodies.push_back(std::move(body));
      continue;
    }
    for (const char* key : {"r0", "rot0", "p0"})
      if (b[key])
        fail(item, loc_of(b[key]),
             "'" + std::string(key) + "' belongs to spatial files (space: 3d); a planar body has "
             "q0: [x, y, phi]");
    check_keys(b, item, {"name", "q0"}, {"mass", "inertia", "com"});
    Body body;
    body.name = name_of(b["name"], item);
    item = "body '" + body.name + "'";
    const YAML::Node q0 = b["q0"];
    if (!q0.IsSequence() || q0.size() != 3)
      fail(item, loc_of(q0), "q0 must be a vector of 3 numbers [x, y, phi]");
    for (int c = 0; c < 3; ++c) body.q0[c] = expr_of(q0[c], item);
    body.loc = loc_of(b);
    BodyMass mass;
    mass.loc = body.loc;
    if (b["mass"]) mass.mass = expr_of(b["mass"], item + " mass");
    if (b["inertia"]) mass.inertia = expr_of(b["inertia"], item + " inertia");
    if (b["com"]) mass.com = vec2_of(b["com"], item + " com");
    m.forces.bodies.push_back(std::move(mass));
    if (m.find_body(body.name)) fail(item, loc_of(b["name"]), "duplicate body name");
    m.bodies.push_back(std::move(body));
  }
}

// The `coordinates:` list: name, q0, kind (length, angle or scalar; default scalar).
void Loader::read_coordinates(const YAML::Node& node, Mechanism& m) {
  if (node.IsNull()) return;
  if (!node.IsSequence())
    fail("coordinates", loc_of(node), "expected a list of coordinates (name, q0, kind)");
  for (std::size_t k = 0; k < node.size(); ++k) {
    const YAML::Node c = node[k];
    std::string item = "coordinates[" + std::to_string(k) + "]";
    if (!c.IsMap()) fail(item, loc_of(c), "expected a mapping with 'name' and 'q0'");
    check_keys(c, item, {"name", "q0"}, {"kind"});
    Coordinate q;
    q.name = name_of(c["name"], item);
    item = "coordinate '" + q.name + "'";
    q.q0 = expr_of(c["q0"], item + " q0");
    q.loc = loc_of(c);
    if (const YAML::Node kind = c["kind"]) {
      const std::string text = kind.IsScalar() ? kind.Scalar() : "";
      if (text == "length")
        q.kind = CoordinateKind::kLength;
      else if (text == "angle")
        q.kind = CoordinateKind::kAngle;
      else if (text == "scalar")
        q.kind = CoordinateKind::kScalar;
      else
        fail(item, loc_of(kind), "kind must be length, angle or scalar");
    }
    for (const Coordinate& other : m.coordinates)
      if (other.name == q.name) fail(item, loc_of(c["name"]), "duplicate coordinate name");
    m.coordinates.push_back(std::move(q));
  }
}

int Loader::body_ref(const YAML::Node& node, const Mechanism& m, const std::string& item,
                     bool allow_ground) {
  if (!node.IsScalar()) fail(item, loc_of(node), "a body reference must be a name");
  const std::string name = node.Scalar();
  if (name == "ground") {
    if (!allow_ground) fail(item, loc_of(node), "this constraint needs a moving body, not ground");
    return kGround;
  }
  if (auto b = m.find_body(name)) return *b;
  fail(item, loc_of(node), "unknown body '" + name + "'");
}

void Loader::read_points(const YAML::Node& node, Mechanism& m) {
  if (node.IsNull()) return;
  if (!node.IsSequence()) fail("points", loc_of(node), "expected a list of points");
  for (std::size_t k = 0; k < node.size(); ++k) {
    const YAML::Node p = node[k];
    std::string item = "points[" + std::to_string(k) + "]";
    if (!p.IsMap()) fail(item, loc_of(p), "expected a mapping with 'name', 'body' and 's'");
    check_keys(p, item, {"name", "body"}, {"s"});
    Point point;
    point.name = name_of(p["name"], item);
    item = "point '" + point.name + "'";
    point.body = body_ref(p["body"], m, item, false);
    const Expr zero{"0", loc_of(p)};
    point.s = p["s"] ? vec_of(p["s"], item + " s") : Vec2{zero, zero, spatial_ ? zero : Expr{}};
    point.loc = loc_of(p);
    m.points.push_back(std::move(point));
  }
}

// Parameters, coordinates (x_<body>, ...) and points share one namespace in expressions and
// CSV headers; a clash would make an expression or a column ambiguous.
void Loader::check_unique_names(const Mechanism& m) {
  std::set<std::string> taken;
  for (const auto& b : m.bodies) {
    if (m.spatial)
      for (const char* prefix : {"x_", "y_", "z_", "e0_", "e1_", "e2_", "e3_"})
        taken.insert(prefix + b.name);
    else
      for (const char* prefix : {"x_", "y_", "phi_"}) taken.insert(prefix + b.name);
  }
  // Coordinates share the one namespace with everything named below.
  for (const auto& q : m.coordinates) {
    const auto named = [&](const auto& list) {
      return std::any_of(list.begin(), list.end(), [&](const auto& x) { return x.name == q.name; });
    };
    if (taken.count(q.name) || m.find_body(q.name) || named(m.parameters) || named(m.definitions) ||
        named(m.points) || named(m.outputs))
      fail("coordinate '" + q.name + "'", q.loc,
           "the name clashes with a body, a parameter, a definition, a point, an output or a "
           "coordinate name (x_<body>, y_<body>, phi_<body>)");
  }
  for (const auto& q : m.coordinates) taken.insert(q.name);
  for (const auto& p : m.parameters) {
    if (taken.count(p.name) || m.find_body(p.name))
      fail("parameters." + p.name, p.loc,
           "the name clashes with a body or a coordinate name (x_<body>, y_<body>, phi_<body>)");
  }
  std::set<std::string> parameter_names;
  for (const auto& p : m.parameters) parameter_names.insert(p.name);
  for (const auto& d : m.definitions)
    if (taken.count(d.name) || m.find_body(d.name) || parameter_names.count(d.name) ||
        d.name == "t" || d.name == "pi")
      fail("definitions." + d.name, d.loc,
           "the name clashes with a parameter, a body, a coordinate name (x_<body>, y_<body>, "
           "phi_<body>), t or pi");
  std::set<std::string> points;
  for (const auto& p : m.points) {
    if (!points.insert(p.name).second)
      fail("point '" + p.name + "'", p.loc, "duplicate point name");
    if (m.find_body(p.name))
      fail("point '" + p.name + "'", p.loc,
           "the name clashes with a body (CSV columns would repeat)");
  }
  // Outputs name CSV columns and header entries, and sit beside the names expressions use.
  std::set<std::string> definition_names;
  for (const auto& d : m.definitions) definition_names.insert(d.name);
  for (const auto& o : m.outputs)
    if (taken.count(o.name) || m.find_body(o.name) || parameter_names.count(o.name) ||
        definition_names.count(o.name) || points.count(o.name))
      fail("outputs." + o.name, o.loc,
           "the name clashes with a body, a point, a parameter, a definition or a coordinate "
           "name (x_<body>, y_<body>, phi_<body>)");
  std::set<std::string> names;
  for (const auto* c : m.constraints())
    if (!c->name.empty() && !names.insert(c->name).second)
      fail(c->item, c->loc, "duplicate joint or driver name '" + c->name + "'");
}

}  // namespace kinegen::codegen::model_detail
