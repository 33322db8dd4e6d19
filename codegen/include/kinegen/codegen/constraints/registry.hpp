// The registry of joint and driver types: what a type must provide, and the one list of them.
//
// A type is one file under codegen/src/constraints/ defining one ConstraintKind: its YAML keys
// (which the loader reads and checks), its equations (GiNaC expressions built from an
// EquationContext), its drawing (what `kinegen animate` shows) and the names of its rows in
// messages. codegen/src/constraints/registry.cpp lists every kind; nothing else names a type.
// See docs/architecture.md, "Adding a joint type".
#pragma once

#include <ginac/ginac.h>

#include <Eigen/Core>
#include <array>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "kinegen/codegen/model/mechanism.hpp"

namespace kinegen::codegen {

class SymbolTable;

// What a key holds, and so how the loader reads it and where it stores it in Constraint.
enum class KeyKind {
  kBody,          // a moving body's name; stored in Constraint::i (key `body`, `i`) or j (`j`)
  kBodyOrGround,  // a body's name or `ground`; stored as kBody
  kOffset,        // [x, y], a point local to a body (a length): Constraint::vectors
  kDirection,     // [x, y], a direction local to a body (not a length): Constraint::vectors
  kValue,         // the joint's constant (Constraint::value); a driver reads `f`, f(t), instead
  kScalar,        // another constant expression: Constraint::scalars
  kEquations,     // one expression string or a list of them, each = 0: Constraint::equations
  kFlag,          // true or false (default_value "false" or "true"): Constraint::flags
  kCoordinate,    // the name of an extra coordinate: Constraint::coordinates
  kCurve,         // [x(u), y(u)], a curve local to a body in one extra coordinate u (the kind's
                  // kCoordinate key that EquationContext::curve is given): Constraint::curves
  kJoint,         // the name of a joint of the file (a spatial driver's): Constraint::joint
};

struct KeySpec {
  const char* name;
  KeyKind kind;
  bool required;
  // Optional keys: what an omitted key means ("0" for a scalar, [0, 0] for a vector).
  const char* default_value = "0";
};

// The symbolic view of one constraint, for its equations: the bodies' coordinates, the rotation
// helper and the key values parsed in the scope the format gives them, each checked (finite
// numbers, defined expressions) and each failure an InputError naming the key and its line.
class EquationContext {
 public:
  using Vec = std::pair<GiNaC::ex, GiNaC::ex>;
  struct Frame {
    GiNaC::ex x, y, phi;
  };
  // Spatial files (spatial_context.cpp): 3-vectors, and a body's origin and Euler parameters.
  using Vec3 = std::array<GiNaC::ex, 3>;
  struct Frame3 {
    Vec3 r;
    std::array<GiNaC::ex, 4> p;
  };

  EquationContext(const Constraint& c, const Mechanism& m, const SymbolTable& symbols,
                  const std::vector<GiNaC::numeric>& param_values)
      : c_(c), m_(m), s_(symbols), values_(param_values) {}

  const Constraint& constraint() const { return c_; }
  // The coordinates of a body (ground: 0, 0, 0).
  Frame frame(int body) const;
  Frame frame_i() const { return frame(c_.i); }
  Frame frame_j() const { return frame(c_.j); }
  // A(phi) s
  static Vec rotate(const GiNaC::ex& phi, const Vec& s);
  // A local vector key (si, sj, s, vi) in the parameters, checked to be finite.
  Vec vector(const std::string& key) const;
  // d_ij = r_j + A_j sj - r_i - A_i si, from the keys si and sj.
  Vec d_ij() const;
  // (A_i vi)^perp . d = -(A_i vi)_y d_x + (A_i vi)_x d_y; vi (key `vi`) must not be zero.
  GiNaC::ex perpendicular(const Vec& d) const;
  // The value: a joint's constant (checked finite) or a driver's f(t) (checked defined).
  GiNaC::ex value() const;
  // A kScalar key in the parameters, checked finite.
  GiNaC::ex scalar(const std::string& key) const;
  // A kFlag key.
  bool flag(const std::string& key) const { return c_.flags.at(key); }
  // The value of a geometry expression (one from vector() or scalar()) at the parameters'
  // values, for checks such as a radius > 0.
  double number(const GiNaC::ex& e) const;
  // An InputError at key `key` of the constraint (its line), for such checks.
  [[noreturn]] void fail(const std::string& key, const std::string& message) const;
  // The rows of an `equations` key: in the coordinates (and t for a driver), checked defined.
  std::vector<GiNaC::ex> equations() const;
  // The symbol of the extra coordinate a kCoordinate key names.
  GiNaC::ex coordinate(const std::string& key) const;
  // A kCurve key as an expression of the coordinate `coordinate_key` names (and the
  // parameters): refuses t, other coordinates, and a curve that is not regular (curve' = 0)
  // at that coordinate's q0, where the mechanism assembles.
  Vec curve(const std::string& key, const std::string& coordinate_key) const;
  // d curve / du of such a curve.
  Vec tangent(const Vec& curve, const std::string& coordinate_key) const;

  // Spatial files. The origin and Euler parameters of a body (ground: 0 and [1, 0, 0, 0]).
  Frame3 frame3(int body) const;
  // A(p) v in the homogeneous form (e0^2 - e.e) v + 2 e (e.v) + 2 e0 e x v, which holds for p
  // of any length, so Phi, Phi_q and gamma come from one expression.
  static Vec3 rotate3(const std::array<GiNaC::ex, 4>& p, const Vec3& v);
  // A 3-vector key, checked finite.
  Vec3 vector3(const std::string& key) const;
  // d_ij = r_j + A_j sj - r_i - A_i si from the keys si and sj (or the points given).
  Vec3 d_ij3() const;
  Vec3 d_ij3(const Vec3& si, const Vec3& sj) const;
  // The body's rotation matrix and origin at the q0 pose (the file's guesses, p normalized).
  Eigen::Matrix3d rotation0(int body) const;
  Eigen::Vector3d origin0(int body) const;
  // The context of the joint a kJoint key names (a driver's `joint`).
  EquationContext joint_context() const;

 private:
  GiNaC::ex geometry(const Expr& e, const std::string& item) const;
  void check_finite(const GiNaC::ex& value, const Expr& e, const std::string& item) const;
  void check_defined(const GiNaC::ex& value, const Expr& e, const std::string& item) const;

  const Constraint& c_;
  const Mechanism& m_;
  const SymbolTable& s_;
  const std::vector<GiNaC::numeric>& values_;
};

// A point fixed in a body (or in ground), in the body's local frame.
struct Attach {
  int body = kGround;
  Eigen::Vector2d s = Eigen::Vector2d::Zero();
};

// What `kinegen animate` draws for the constraints, in numbers; each type adds its pieces.
struct Sketch {
  // A slider block: `point` runs on the line through `origin` along `dir` (unit), both local
  // to `guide`.
  struct Slider {
    Attach point;
    int guide = kGround;
    Eigen::Vector2d origin = Eigen::Vector2d::Zero(), dir = Eigen::Vector2d::UnitX();
  };
  std::vector<Attach> landmarks;  // points a body's outline passes through
  std::vector<Attach> pins;       // revolute pins
  std::vector<Eigen::Vector2d> ground_pivots;
  std::vector<Slider> sliders;
  std::vector<std::pair<Attach, Attach>> struts;  // distance constraints
  // A pitch circle of a gear or pinion about `centre`, with a radius mark along the body's
  // local x axis (so its rotation shows).
  struct Circle {
    Attach centre;
    double radius = 0;
  };
  std::vector<Circle> pitch_circles;
  // A rack's pitch line: the line through `origin` along `dir` in `guide`, drawn over the
  // travel of `point` (the pinion's centre) along it, like a slider's guide.
  std::vector<Slider> pitch_lines;
  std::vector<Attach> welds;  // fixed joints: the bodies are joined at the point
  // Slot curves and cam profiles: polylines sampled in the body's frame.
  struct Curve {
    int body = kGround;
    std::vector<Eigen::Vector2d> points;
  };
  std::vector<Curve> curves;
};

// The numeric view of one constraint, for its drawing (parameters substituted).
struct DrawContext {
  const Constraint& constraint;
  std::function<double(const Expr&)> number;  // a geometry expression's value

  Eigen::Vector2d vector(const std::string& key) const {
    const Vec2& v = constraint.vector(key);
    return {number(v.x), number(v.y)};
  }
  double value() const { return number(constraint.value); }
  double scalar(const std::string& key) const { return number(constraint.scalars.at(key)); }
  // A kCurve key at the value u of its coordinate.
  std::function<Eigen::Vector2d(const std::string& curve_key, double u)> curve_point = nullptr;
  // The range to draw a curve over: its coordinate's travel over the analysis with a margin,
  // a whole turn for an angle (a cam's profile, a roller).
  std::function<std::pair<double, double>(int coordinate)> curve_range = nullptr;

  // The curve `key` (in coordinate key `coordinate_key`) of `body` as a polyline.
  Sketch::Curve sampled_curve(int body, const std::string& key,
                              const std::string& coordinate_key) const;
};

// Which files a type belongs to: a type name resolves by the file's `space`, so `revolute` in a
// spatial file is the spatial revolute.
enum class KindSpace { kPlanar, kSpatial, kBoth };

struct ConstraintKind {
  const char* name;    // the `type` in the file
  bool joint, driver;  // whether it may appear under `joints`, under `drivers`
  // Every key besides `type` and `name`, in the order they are read; messages list the
  // required ones first. For a driver the kValue key is replaced by a required `f`.
  std::vector<KeySpec> keys;
  // Rows of Phi; 0: one per entry of the kEquations key.
  int rows;
  std::vector<GiNaC::ex> (*equations)(const EquationContext& context);
  // Adds what animate draws; nullptr draws nothing (the bodies are drawn all the same).
  void (*draw)(const DrawContext& context, Sketch& sketch) = nullptr;
  // How a message names row `component` (0-based) when the type has more than one row
  // ("x-component" in "joints[1] (revolute) x-component").
  std::string (*row_name)(const Constraint& c, int component) = nullptr;
  // At assembly (the first solved position of an analysis, coordinates q): a `warning:`
  // message about this constraint (without its file, line and item, which the analysis adds),
  // or "" (a gear's centre distance off its pitch radii).
  std::string (*assembly_warning)(const DrawContext& context, const Eigen::VectorXd& q) = nullptr;
  // Kinetostatics (forces.hpp): the keys of the points where the reaction acts on body i and
  // on body j (nullptr: the body's origin).
  const char* reaction_i = nullptr;
  const char* reaction_j = nullptr;
  // false: the rows are not a joint between two bodies (expression): no reaction columns, and
  // a driver has one effort per row.
  bool reaction = true;
  // Phi is |d|^2 - f^2: a driver's effort is -2 lambda |d| rather than -lambda.
  bool squared_distance = false;
  // A cam contact: adds the column J.fn, the force on j along the normal of curve_i (positive
  // in compression, see forces.hpp).
  bool normal_force = false;
  KindSpace space = KindSpace::kPlanar;

  bool in_space(bool spatial) const {
    return space == KindSpace::kBoth || (space == KindSpace::kSpatial) == spatial;
  }
  const KeySpec* key(const std::string& key_name) const {
    for (const auto& k : keys)
      if (key_name == k.name) return &k;
    return nullptr;
  }
};

// Every registered kind, in the order messages list them.
const std::vector<const ConstraintKind*>& constraint_kinds();
// The kind called `name` in a planar (spatial) file, or nullptr.
const ConstraintKind* find_constraint_kind(const std::string& name, bool spatial = false);

// The local vectors of `c` that are lengths (kOffset keys), each with the body it is local to
// (sj: body j, the others: body i), for the coordinates' tolerance scales.
std::vector<std::pair<int, const Vec2*>> offsets(const Constraint& c);
// The point of a reaction: the vector key `key` of `c`, or [0, 0] for nullptr.
Vec2 reaction_point(const Constraint& c, const char* key);

}  // namespace kinegen::codegen
