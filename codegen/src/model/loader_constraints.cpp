// Loader (loader.hpp): joints and drivers: the type, the keys it declares (constraints/
// registry.hpp) and a driver's law.
#include <algorithm>
#include <cctype>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_set>
#include <vector>

#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "loader.hpp"

namespace kinegen::codegen::model_detail {

void Loader::read_constraints(const YAML::Node& node, const std::string& list, bool driver,
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
    const ConstraintKind* kind = find_constraint_kind(type_name, spatial_);
    if (!kind && find_constraint_kind(type_name, !spatial_))
      fail(item, loc_of(c["type"]),
           "the type '" + type_name + "' exists only in " +
               (spatial_ ? "planar files" : "spatial files (space: 3d)"));
    if (!kind || !allowed_kind(kind)) {
      std::string allowed;
      for (const ConstraintKind* t : constraint_kinds())
        if (t->in_space(spatial_) && allowed_kind(t)) allowed += (allowed.empty() ? "" : ", ") + std::string(t->name);
      fail(item, loc_of(c["type"]),
           "unknown " + std::string(free ? "free" : driver ? "driver" : "joint") + " type '" +
               type_name + "' (expected one of: " + allowed + ")");
    }
    Constraint con;
    con.kind = kind;
    con.is_driver = driver;
    con.loc = loc_of(c);
    if (free) con.free = Constraint::Free{};  // not emplace(): clang sees Free as incomplete here
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

bool Loader::has_value_key(const ConstraintKind& kind) {
  return std::any_of(kind.keys.begin(), kind.keys.end(),
                     [](const KeySpec& k) { return k.kind == KeyKind::kValue; });
}

// The keys of `kind` from `c` into `con`: bodies first (then i != j), the rest in the
// kind's order; omitted optional keys take their defaults.
void Loader::read_keys(const YAML::Node& c, const ConstraintKind& kind, const std::string& item,
                       const Mechanism& m, Constraint& con) {
  const bool driver = con.is_driver;
  std::vector<std::string> required = {"type"}, optional = {"name"};
  bool has_law = false;  // a driver with an f(t): pieces, period and table apply
  for (const KeySpec& k : kind.keys) {
    has_law = has_law || (driver && k.kind == KeyKind::kValue);
    (k.required && !(driver && k.kind == KeyKind::kValue) ? required : optional)
        .push_back(key_name(k, driver));
  }
  if (con.free) {
    // Written like a driver without f: value0 and v0 instead.
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
  for (const KeySpec& k : kind.keys)
    if (!is_body(k)) read_key(c, k, item, m, con);
}

// One key of `con`'s type (not a body) from `c`, or its default.
void Loader::read_key(const YAML::Node& c, const KeySpec& k, const std::string& item,
                      const Mechanism& m, Constraint& con) {
  const bool driver = con.is_driver;
  const std::string key = key_name(k, driver);
  const YAML::Node node = c[key];
  const Expr fallback{k.default_value, con.loc};
  switch (k.kind) {
    case KeyKind::kOffset:
    case KeyKind::kDirection:
      con.vectors[key] = node ? vec_of(node, item + " " + key)
                              : Vec2{fallback, fallback, spatial_ ? fallback : Expr{}};
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
    case KeyKind::kJoint:
      con.joint = joint_ref(node, m, item + " " + key);
      break;
    case KeyKind::kBody:
    case KeyKind::kBodyOrGround:
      break;
  }
}

// A driver's law: f as one expression, as pieces or as `input`; or a table; and
// an optional period. The pieces' order and the period's sign need the parameters'
// values, so the symbolic stage checks them.
void Loader::read_law(const YAML::Node& c, const std::string& item, Constraint& con) {
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
      fail(
          item + " table", loc_of(table),
          "a periodic table must start at t = 0 (its first t is " + format_number(t.front()) + ")");
    const Spline spline = law.period ? fit_periodic(t, v) : fit_not_a_knot(t, v);
    check_spline(spline, law.table, src);
    law.table_ref = register_table(spline, src);
    law.table_id = law.table_ref->id();
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

}  // namespace kinegen::codegen::model_detail
