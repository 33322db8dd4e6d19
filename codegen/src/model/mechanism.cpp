// Reads a mechanism file into plain data and validates its structure: keys, types, names,
// references and vector lengths. Expressions stay text; the symbolic stage parses them.
#include "kinegen/codegen/model/mechanism.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <unordered_set>

#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "kinegen/codegen/symbolic/functions.hpp"

namespace kinegen::codegen {

namespace {

SourceLoc loc_of(const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  if (mark.line < 0) return {};
  return {mark.line + 1, mark.column + 1};
}

// C++ keywords and alternative tokens (C++20), which a name must not be.
const std::unordered_set<std::string>& cpp_keywords() {
  static const std::unordered_set<std::string> kKeywords = {
      "alignas",   "alignof",      "and",          "and_eq",      "asm",
      "auto",      "bitand",       "bitor",        "bool",        "break",
      "case",      "catch",        "char",         "char8_t",     "char16_t",
      "char32_t",  "class",        "compl",        "concept",     "const",
      "consteval", "constexpr",    "constinit",    "const_cast",  "continue",
      "co_await",  "co_return",    "co_yield",     "decltype",    "default",
      "delete",    "do",           "double",       "dynamic_cast", "else",
      "enum",      "explicit",     "export",       "extern",      "false",
      "float",     "for",          "friend",       "goto",        "if",
      "inline",    "int",          "long",         "mutable",     "namespace",
      "new",       "noexcept",     "not",          "not_eq",      "nullptr",
      "operator",  "or",           "or_eq",        "private",     "protected",
      "public",    "register",     "reinterpret_cast", "requires", "return",
      "short",     "signed",       "sizeof",       "static",      "static_assert",
      "static_cast", "struct",     "switch",       "template",    "this",
      "thread_local", "throw",     "true",         "try",         "typedef",
      "typeid",    "typename",     "union",        "unsigned",    "using",
      "virtual",   "void",         "volatile",     "wchar_t",     "while",
      "xor",       "xor_eq",       "final",        "override",    "import",
      "module"};
  return kKeywords;
}

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

constexpr std::size_t kMaxExpressionLength = 4096;
constexpr int kMaxNesting = 64;
constexpr std::size_t kMaxPieces = 1000;
constexpr std::size_t kMaxFileSize = 1 << 20;

class Loader {
 public:
  explicit Loader(std::string source) : source_(std::move(source)) {}

  Mechanism load(const YAML::Node& root) {
    if (!root.IsDefined() || root.IsNull()) fail("file", {}, "the file is empty");
    if (!root.IsMap()) fail("file", loc_of(root), "the top level must be a mapping of keys");
    check_keys(root, "file", {"name"},
               {"parameters", "definitions", "bodies", "coordinates", "joints", "drivers", "points",
                "outputs", "gravity", "forces", "free", "stop_when"});
    Mechanism m;
    m.source = source_;
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
    if (root["outputs"]) read_outputs(root["outputs"], m);
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

 private:
  [[noreturn]] void fail(const std::string& item, SourceLoc loc, const std::string& message) {
    throw InputError(source_, item, loc, message);
  }

  // Every key must be known (catches misspellings) and appear once.
  void check_keys(const YAML::Node& map, const std::string& item,
                  const std::vector<std::string>& required,
                  const std::vector<std::string>& optional) {
    std::set<std::string> seen;
    for (auto it = map.begin(); it != map.end(); ++it) {
      if (!it->first.IsScalar()) fail(item, loc_of(it->first), "keys must be plain names");
      const std::string key = it->first.Scalar();
      if (!seen.insert(key).second) fail(item, loc_of(it->first), "duplicate key '" + key + "'");
      const bool known = key == "type" || key == "name" ||
                         std::find(required.begin(), required.end(), key) != required.end() ||
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

  std::string name_of(const YAML::Node& node, const std::string& item) {
    if (!node.IsScalar()) fail(item, loc_of(node), "a name must be a plain string");
    const std::string name = node.Scalar();
    if (!is_valid_identifier(name))
      fail(item, loc_of(node),
           "'" + name +
               "' is not a valid name (a C identifier that is not a C++ keyword and does not "
               "start with '_' or contain '__')");
    if (reserved_names().count(name))
      fail(item, loc_of(node), "'" + name + "' is reserved in expressions");
    return name;
  }

  Expr expr_of(const YAML::Node& node, const std::string& item) {
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
  bool flag_of(const YAML::Node& node, const std::string& item) {
    bool value = false;
    if (!node.IsScalar() || !YAML::convert<bool>::decode(node, value))
      fail(item, loc_of(node), "expected true or false");
    return value;
  }

  Vec2 vec2_of(const YAML::Node& node, const std::string& item) {
    if (!node.IsSequence() || node.size() != 2)
      fail(item, loc_of(node), "expected a vector of 2 numbers, e.g. [0, 0]");
    return Vec2{expr_of(node[0], item), expr_of(node[1], item)};
  }

  // `parameters:` and `definitions:`: a mapping of names to expressions, in file order.
  template <class Named>
  void read_named(const YAML::Node& node, const std::string& section, const std::string& what,
                  std::vector<Named>& out) {
    if (node.IsNull()) return;
    if (!node.IsMap()) fail(section, loc_of(node), "expected a mapping name: " + what);
    std::set<std::string> seen;
    for (auto it = node.begin(); it != node.end(); ++it) {
      const std::string name = name_of(it->first, section);
      const std::string item = section + "." + name;
      if (!seen.insert(name).second) fail(item, loc_of(it->first), "duplicate name");
      out.push_back({name, expr_of(it->second, item), loc_of(it->first)});
    }
  }

  void read_outputs(const YAML::Node& node, Mechanism& m) {
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

  void read_bodies(const YAML::Node& node, Mechanism& m) {
    if (!node.IsSequence() || node.size() == 0)
      fail("bodies", loc_of(node), "expected a non-empty list of bodies");
    for (std::size_t k = 0; k < node.size(); ++k) {
      const YAML::Node b = node[k];
      std::string item = "bodies[" + std::to_string(k) + "]";
      if (!b.IsMap()) fail(item, loc_of(b), "expected a mapping with 'name' and 'q0'");
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

  // `coordinates:` (format 6.1): name, q0, kind (length, angle or scalar; default scalar).
  void read_coordinates(const YAML::Node& node, Mechanism& m) {
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

  int body_ref(const YAML::Node& node, const Mechanism& m, const std::string& item,
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

  void read_constraints(const YAML::Node& node, const std::string& list, bool driver,
                        Mechanism& m) {
    if (!node || node.IsNull()) return;
    if (!node.IsSequence()) fail(list, loc_of(node), "expected a list");
    for (std::size_t k = 0; k < node.size(); ++k) {
      const YAML::Node c = node[k];
      std::string item = list + "[" + std::to_string(k) + "]";
      if (!c.IsMap()) fail(item, loc_of(c), "expected a mapping with a 'type'");
      if (!c["type"] || !c["type"].IsScalar()) fail(item, loc_of(c), "missing key 'type'");
      const std::string type_name = c["type"].Scalar();
      const bool free = list == "free";
      // A free item measures one quantity: a driver type with a value (not `expression`).
      const auto allowed_kind = [&](const ConstraintKind* t) {
        return free ? t->driver && t->rows == 1 && has_value_key(*t)
                    : (driver ? t->driver : t->joint);
      };
      const ConstraintKind* kind = find_constraint_kind(type_name);
      if (!kind || !allowed_kind(kind)) {
        std::string allowed;
        for (const ConstraintKind* t : constraint_kinds())
          if (allowed_kind(t)) allowed += (allowed.empty() ? "" : ", ") + std::string(t->name);
        fail(item, loc_of(c["type"]),
             "unknown " + std::string(free ? "free" : driver ? "driver" : "joint") + " type '" +
                 type_name + "' (expected one of: " + allowed + ")");
      }
      Constraint con;
      con.kind = kind;
      con.is_driver = driver;
      con.loc = loc_of(c);
      if (free) con.free.emplace();
      item += " (" + type_name + ")";
      if (c["name"]) {
        con.name = name_of(c["name"], item);
        item = list + "[" + std::to_string(k) + "] '" + con.name + "' (" + type_name + ")";
      }
      con.item = item;
      read_keys(c, *kind, item, m, con);
      // A free coordinate's value, rate and acceleration are run-time inputs named after it
      // (its CSV columns Z, Z.v, Z.a; generated Params members).
      if (free && con.name.empty()) con.name = "free" + std::to_string(k);
      (driver ? m.drivers : m.joints).push_back(std::move(con));
    }
  }

  static bool has_value_key(const ConstraintKind& kind) {
    return std::any_of(kind.keys.begin(), kind.keys.end(),
                       [](const KeySpec& k) { return k.kind == KeyKind::kValue; });
  }

  // A driver's kValue key is `f`, its f(t), and always required.
  static std::string key_name(const KeySpec& k, bool driver) {
    return driver && k.kind == KeyKind::kValue ? "f" : k.name;
  }

  // The keys of `kind` from `c` into `con`: bodies first (then i != j), the rest in the
  // kind's order; omitted optional keys take their defaults.
  void read_keys(const YAML::Node& c, const ConstraintKind& kind, const std::string& item,
                 const Mechanism& m, Constraint& con) {
    const bool driver = con.is_driver;
    std::vector<std::string> required, optional;
    bool has_law = false;  // a driver with an f(t): pieces, period and table apply
    for (const KeySpec& k : kind.keys) {
      has_law = has_law || (driver && k.kind == KeyKind::kValue);
      (k.required && !(driver && k.kind == KeyKind::kValue) ? required : optional)
          .push_back(key_name(k, driver));
    }
    if (con.free) {
      // Written like a driver without f (format 7.1): value0 and v0 instead.
      std::erase(optional, std::string("f"));
      optional.push_back("value0");
      optional.push_back("v0");
      has_law = false;
    }
    if (has_law) {
      optional.push_back("period");
      optional.push_back("table");
    }
    check_keys(c, item, required, optional);
    if (has_law) {
      if (c["f"] && c["table"]) fail(item, loc_of(c["table"]), "give either f or table, not both");
      if (!c["f"] && !c["table"]) fail(item, loc_of(c), "missing key 'f' (or 'table')");
    }

    const auto is_body = [](const KeySpec& k) {
      return k.kind == KeyKind::kBody || k.kind == KeyKind::kBodyOrGround;
    };
    for (const KeySpec& k : kind.keys) {
      if (!is_body(k) || !c[k.name]) continue;
      (std::string(k.name) == "j" ? con.j : con.i) =
          body_ref(c[k.name], m, item, k.kind == KeyKind::kBodyOrGround);
    }
    if (c["i"] && c["j"] && con.i == con.j)
      fail(item, loc_of(c["j"]), "i and j must be different bodies");
    for (const KeySpec& k : kind.keys) {
      if (is_body(k)) continue;
      const std::string key = key_name(k, driver);
      const YAML::Node node = c[key];
      const Expr fallback{k.default_value, con.loc};
      switch (k.kind) {
        case KeyKind::kOffset:
        case KeyKind::kDirection:
          con.vectors[key] = node ? vec2_of(node, item + " " + key) : Vec2{fallback, fallback};
          break;
        case KeyKind::kValue:
          if (con.free) {
            if (c["value0"]) con.free->value0 = expr_of(c["value0"], item + " value0");
            if (c["v0"]) con.free->v0 = expr_of(c["v0"], item + " v0");
            con.law.input = true;
            con.value = Expr{"0", con.loc};
          } else if (driver) {
            read_law(c, item, con);
          } else {
            con.value = node ? expr_of(node, item + " " + key) : fallback;
          }
          break;
        case KeyKind::kScalar:
          con.scalars[key] = node ? expr_of(node, item + " " + key) : fallback;
          break;
        case KeyKind::kEquations:
          if (node.IsScalar()) {
            con.equations.push_back(expr_of(node, item));
          } else if (node.IsSequence() && node.size() > 0) {
            for (std::size_t e = 0; e < node.size(); ++e)
              con.equations.push_back(
                  expr_of(node[e], item + " " + key + "[" + std::to_string(e) + "]"));
          } else {
            fail(item, loc_of(node), key + " must be a non-empty list of expression strings");
          }
          break;
        case KeyKind::kFlag:
          con.flags[key] =
              node ? flag_of(node, item + " " + key) : std::string(k.default_value) == "true";
          break;
        case KeyKind::kCurve:
          con.curves[key] = vec2_of(node, item + " " + key);
          break;
        case KeyKind::kCoordinate: {
          if (!node.IsScalar()) fail(item, loc_of(node), key + " must be a coordinate's name");
          const std::string name = node.Scalar();
          const auto it = std::find_if(m.coordinates.begin(), m.coordinates.end(),
                                       [&](const Coordinate& q) { return q.name == name; });
          if (it == m.coordinates.end())
            fail(item, loc_of(node),
                 key + ": unknown coordinate '" + name + "' (declare it under coordinates:)");
          con.coordinates[key] = static_cast<int>(it - m.coordinates.begin());
          break;
        }
        case KeyKind::kBody:
        case KeyKind::kBodyOrGround:
          break;
      }
    }
  }

  // A driver's law (format 6.3): f as one expression, as pieces or as `input`; or a table;
  // and an optional period. The pieces' order and the period's sign need the parameters'
  // values, so the symbolic stage checks them.
  void read_law(const YAML::Node& c, const std::string& item, Constraint& con) {
    DriverLaw& law = con.law;
    if (c["period"]) law.period = expr_of(c["period"], item + " period");
    if (const YAML::Node table = c["table"]) {
      if (!table.IsScalar() || table.Scalar().empty())
        fail(item, loc_of(table), "table must be the path of a CSV file");
      law.table = table.Scalar();
      law.table_loc = loc_of(table);
      con.value = Expr{"0", loc_of(table)};
      const TableSource src{source_, item + " table", loc_of(table), true};
      std::vector<double> t, v;
      read_table(law.table, src, t, v);
      if (law.period && t.front() != 0)
        fail(item + " table", loc_of(table),
             "a periodic table must start at t = 0 (its first t is " + format_number(t.front()) +
                 ")");
      law.table_id = register_table(law.period ? fit_periodic(t, v) : fit_not_a_knot(t, v));
      return;
    }
    const YAML::Node f = c["f"];
    if (f.IsScalar() && f.Scalar() == "input") {
      if (law.period) fail(item, loc_of(c["period"]), "an input driver has no period");
      if (con.name.empty())
        fail(item, loc_of(f),
             "an input driver needs a name: its run-time inputs are the generated Params' NAME, "
             "NAME_v and NAME_a, and `analyze --input NAME=FILE.csv` gives them");
      law.input = true;
      con.value = Expr{"0", loc_of(f)};
      return;
    }
    if (!f.IsSequence()) {
      if (law.period)
        fail(item, loc_of(c["period"]),
             "period applies to a driver in pieces or a table; a single expression f repeats "
             "by itself if it should");
      con.value = expr_of(f, item + " f");
      return;
    }
    if (f.size() == 0) fail(item, loc_of(f), "f must have at least one piece");
    if (f.size() > kMaxPieces)
      fail(item, loc_of(f), "f has more than " + std::to_string(kMaxPieces) + " pieces");
    for (std::size_t k = 0; k < f.size(); ++k) {
      const YAML::Node p = f[k];
      const std::string piece = item + " f[" + std::to_string(k) + "]";
      if (!p.IsMap()) fail(piece, loc_of(p), "a piece is a map {until: T, f: E}");
      const bool last = k + 1 == f.size();
      if (last)
        check_keys(p, piece, {"f"}, {});
      else
        check_keys(p, piece, {"until", "f"}, {});
      law.pieces.push_back({last ? Expr{"", loc_of(p)} : expr_of(p["until"], piece + " until"),
                            expr_of(p["f"], piece + " f"), loc_of(p)});
    }
    con.value = law.pieces.front().f;
  }

  // Applied loads (format 6.5). Defaults beyond the spec's: s, si, sj [0, 0]; damping 0;
  // rotational angle0 0.
  void read_forces(const YAML::Node& node, Mechanism& m) {
    if (node.IsNull()) return;
    if (!node.IsSequence()) fail("forces", loc_of(node), "expected a list of loads");
    struct Kind {
      const char* name;
      Load::Kind kind;
      std::vector<std::string> required, optional;
    };
    static const Kind kKinds[] = {
        {"force", Load::Kind::kForce, {"body", "f"}, {"s"}},
        {"torque", Load::Kind::kTorque, {"body", "value"}, {}},
        {"spring_damper", Load::Kind::kSpringDamper, {"i", "j", "stiffness", "length0"},
         {"si", "sj", "damping", "preload"}},
        {"rotational_spring_damper", Load::Kind::kRotationalSpringDamper,
         {"i", "j", "stiffness"}, {"damping", "angle0"}},
    };
    for (std::size_t k = 0; k < node.size(); ++k) {
      const YAML::Node f = node[k];
      std::string item = "forces[" + std::to_string(k) + "]";
      if (!f.IsMap()) fail(item, loc_of(f), "expected a mapping with a 'type'");
      if (!f["type"] || !f["type"].IsScalar()) fail(item, loc_of(f), "missing key 'type'");
      const std::string type_name = f["type"].Scalar();
      const Kind* kind = nullptr;
      for (const auto& kk : kKinds)
        if (type_name == kk.name) kind = &kk;
      if (!kind)
        fail(item, loc_of(f["type"]),
             "unknown load type '" + type_name +
                 "' (expected one of: force, torque, spring_damper, rotational_spring_damper)");
      Load load;
      load.kind = kind->kind;
      load.loc = loc_of(f);
      item += " (" + type_name + ")";
      if (f["name"]) {
        load.name = name_of(f["name"], item);
        item = "forces[" + std::to_string(k) + "] '" + load.name + "' (" + type_name + ")";
      }
      load.item = item;
      check_keys(f, item, kind->required, kind->optional);
      const Expr zero{"0", load.loc};
      load.s = load.si = load.sj = Vec2{zero, zero};
      load.damping = load.preload = load.angle0 = zero;
      if (f["body"]) load.body = body_ref(f["body"], m, item, false);
      if (f["i"]) load.i = body_ref(f["i"], m, item, true);
      if (f["j"]) load.j = body_ref(f["j"], m, item, true);
      if (f["i"] && load.i == load.j)
        fail(item, loc_of(f["j"]), "i and j must be different bodies");
      if (f["s"]) load.s = vec2_of(f["s"], item + " s");
      if (f["si"]) load.si = vec2_of(f["si"], item + " si");
      if (f["sj"]) load.sj = vec2_of(f["sj"], item + " sj");
      if (f["f"]) load.f = vec2_of(f["f"], item + " f");
      if (f["value"]) load.value = expr_of(f["value"], item + " value");
      if (f["stiffness"]) load.stiffness = expr_of(f["stiffness"], item + " stiffness");
      if (f["damping"]) load.damping = expr_of(f["damping"], item + " damping");
      if (f["length0"]) load.length0 = expr_of(f["length0"], item + " length0");
      if (f["preload"]) load.preload = expr_of(f["preload"], item + " preload");
      if (f["angle0"]) load.angle0 = expr_of(f["angle0"], item + " angle0");
      m.forces.loads.push_back(std::move(load));
    }
  }

  void read_points(const YAML::Node& node, Mechanism& m) {
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
      point.s = p["s"] ? vec2_of(p["s"], item + " s") : Vec2{zero, zero};
      point.loc = loc_of(p);
      m.points.push_back(std::move(point));
    }
  }

  // Parameters, coordinates (x_<body>, ...) and points share one namespace in expressions and
  // CSV headers; a clash would make an expression or a column ambiguous.
  void check_unique_names(const Mechanism& m) {
    std::set<std::string> taken;
    for (const auto& b : m.bodies)
      for (const char* prefix : {"x_", "y_", "phi_"}) taken.insert(prefix + b.name);
    // Coordinates share the one namespace (format 6.1) with everything named below.
    for (const auto& q : m.coordinates) {
      const auto named = [&](const auto& list) {
        return std::any_of(list.begin(), list.end(),
                           [&](const auto& x) { return x.name == q.name; });
      };
      if (taken.count(q.name) || m.find_body(q.name) || named(m.parameters) ||
          named(m.definitions) || named(m.points) || named(m.outputs))
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
      if (!points.insert(p.name).second) fail("point '" + p.name + "'", p.loc, "duplicate point name");
      if (m.find_body(p.name))
        fail("point '" + p.name + "'", p.loc, "the name clashes with a body (CSV columns would repeat)");
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

  std::string source_;
};

}  // namespace

const char* Constraint::type_name() const { return kind ? kind->name : "?"; }

int Constraint::equation_count() const {
  return kind->rows > 0 ? kind->rows : static_cast<int>(equations.size());
}

const Vec2& Constraint::vector(const std::string& key) const {
  const auto it = vectors.find(key);
  if (it == vectors.end()) throw std::logic_error(item + " has no vector key '" + key + "'");
  return it->second;
}

int Mechanism::nc() const {
  int n = 0;
  for (const auto* c : constraints()) n += c->equation_count();
  return n;
}

std::vector<const Constraint*> Mechanism::constraints() const {
  std::vector<const Constraint*> all;
  for (const auto& c : joints) all.push_back(&c);
  for (const auto& c : drivers) all.push_back(&c);
  return all;
}

std::vector<int> Mechanism::free_drivers() const {
  std::vector<int> out;
  for (std::size_t k = 0; k < drivers.size(); ++k)
    if (drivers[k].free) out.push_back(static_cast<int>(k));
  return out;
}

std::optional<int> Mechanism::find_body(const std::string& name) const {
  for (std::size_t k = 0; k < bodies.size(); ++k)
    if (bodies[k].name == name) return static_cast<int>(k);
  return std::nullopt;
}

bool is_valid_identifier(const std::string& name) {
  if (name.empty() || name.size() > 64) return false;
  if (!(std::isalpha(static_cast<unsigned char>(name[0])))) return false;  // also rules out '_X'
  for (char ch : name)
    if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '_')) return false;
  if (name.find("__") != std::string::npos) return false;
  return cpp_keywords().count(name) == 0;
}

Mechanism parse_mechanism(const std::string& yaml_text, const std::string& source) {
  if (yaml_text.size() > kMaxFileSize)
    throw InputError(source, "file", {},
                     "the file is larger than " + std::to_string(kMaxFileSize) +
                         " bytes; a mechanism file is far smaller");
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::ParserException& e) {
    throw InputError(source, "YAML syntax", {e.mark.line + 1, e.mark.column + 1}, e.msg);
  }
  return Loader(source).load(root);
}

Mechanism load_mechanism(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "file", {}, "cannot open the mechanism file");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_mechanism(text.str(), path);
}

std::vector<std::string> coordinate_labels(const Mechanism& m) {
  std::vector<std::string> labels;
  for (const auto& b : m.bodies)
    for (const char* c : {".x", ".y", ".phi"}) labels.push_back(b.name + c);
  for (const auto& c : m.coordinates) labels.push_back(c.name);
  return labels;
}

}  // namespace kinegen::codegen
