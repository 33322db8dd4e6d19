// The mechanism file's loader (model stage): the Loader class, whose members read each section
// of the file: loader.cpp (the file, names, expressions, bodies, coordinates, points, outputs),
// loader_constraints.cpp (joints and drivers: the keys their types declare, the laws),
// loader_forces.cpp (masses and loads). Private to the stage; mechanism.cpp calls it.
#pragma once

#include <yaml-cpp/yaml.h>

#include <string>
#include <utility>
#include <vector>

#include "kinegen/codegen/base/read_file.hpp"
#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/model/mechanism.hpp"

namespace kinegen::codegen::model_detail {

// The YAML line and column of a node (none for a node without a mark).
SourceLoc loc_of(const YAML::Node& node);

// Limits on what a file may hold: an expression's length and nesting, a law's pieces, the
// file's size.
constexpr std::size_t kMaxExpressionLength = 4096;
constexpr int kMaxNesting = 64;
constexpr std::size_t kMaxPieces = 1000;
constexpr std::size_t kMaxFileSize = kMaxMechanismBytes;  // base/read_file.hpp
// A name's length (is_valid_identifier refuses longer ones too; the loader says why).
constexpr std::size_t kMaxNameLength = 64;

class Loader {
 public:
  explicit Loader(std::string source) : source_(std::move(source)) {}
  Mechanism load(const YAML::Node& root);

 private:
  [[noreturn]] void fail(const std::string& item, SourceLoc loc, const std::string& message) {
    throw InputError(source_, item, loc, message);
  }
  // Every key must be known (catches misspellings) and appear once.
  void check_keys(const YAML::Node& map, const std::string& item,
                  const std::vector<std::string>& required,
                  const std::vector<std::string>& optional);
  std::string name_of(const YAML::Node& node, const std::string& item);
  Expr expr_of(const YAML::Node& node, const std::string& item);
  // YAML's true/false (and its other spellings: True, FALSE, yes, no, on, off).
  bool flag_of(const YAML::Node& node, const std::string& item);
  Vec2 vec2_of(const YAML::Node& node, const std::string& item);
  // A vector of the file's space: [x, y], or [x, y, z] in a spatial file.
  Vec2 vec_of(const YAML::Node& node, const std::string& item);
  // Spatial files (loader_spatial.cpp, docs/format.md, Spatial mechanisms): `space`, which
  // top-level keys a spatial file may not have yet, a body's pose, `vectors:` and the
  // normalization rows.
  void read_space(const YAML::Node& root, Mechanism& m);
  void read_spatial_pose(const YAML::Node& b, const std::string& item, Body& body);
  void read_vectors(const YAML::Node& node, Mechanism& m);
  void add_normalization(Mechanism& m);
  // `suspension:` (loader_suspension.cpp): validated, its outputs appended to m.outputs.
  // `key`: where the block's key stands (its messages point there).
  void read_suspension(const YAML::Node& node, SourceLoc key, Mechanism& m);
  // Its `springs:`: the outputs (indices) that give a spring's length.
  std::vector<int> read_springs(const YAML::Node& springs, const Mechanism& m);
  // A kJoint key: the index of the joint it names.
  int joint_ref(const YAML::Node& node, const Mechanism& m, const std::string& item);
  bool spatial_ = false;
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
  void read_outputs(const YAML::Node& node, Mechanism& m);
  void read_bodies(const YAML::Node& node, Mechanism& m);
  // The `coordinates:` list: name, q0, kind (length, angle or scalar; default scalar).
  void read_coordinates(const YAML::Node& node, Mechanism& m);
  int body_ref(const YAML::Node& node, const Mechanism& m, const std::string& item,
               bool allow_ground);
  void read_constraints(const YAML::Node& node, const std::string& list, bool driver, Mechanism& m);
  static bool has_value_key(const ConstraintKind& kind);
  // A driver's kValue key is `f`, its f(t), and always required.
  static std::string key_name(const KeySpec& k, bool driver) {
    return driver && k.kind == KeyKind::kValue ? "f" : k.name;
  }
  // The keys of `kind` from `c` into `con`: bodies first (then i != j), the rest in the
  // kind's order; omitted optional keys take their defaults.
  void read_keys(const YAML::Node& c, const ConstraintKind& kind, const std::string& item,
                 const Mechanism& m, Constraint& con);
  // A driver's law: f as one expression, as pieces or as `input`; or a table; and
  // an optional period. The pieces' order and the period's sign need the parameters'
  // values, so the symbolic stage checks them.
  void read_key(const YAML::Node& c, const KeySpec& k, const std::string& item, const Mechanism& m,
                Constraint& con);
  void read_law(const YAML::Node& c, const std::string& item, Constraint& con);
  // Applied loads (docs/format.md: Loads), with their defaults: s, si, sj [0, 0]; damping 0;
  // rotational angle0 0.
  void read_forces(const YAML::Node& node, Mechanism& m);
  void read_load_inputs(Load& load, const Mechanism& m);
  void read_points(const YAML::Node& node, Mechanism& m);
  // Parameters, coordinates (x_<body>, ...) and points share one namespace in expressions and
  // CSV headers; a clash would make an expression or a column ambiguous.
  void check_unique_names(const Mechanism& m);
  std::string source_;
};

}  // namespace kinegen::codegen::model_detail
