// The mechanism stage: plain, validated data read from a mechanism file.
//
// Nothing here knows GiNaC. Expressions are kept as text with the place they came from, so the
// symbolic stage can parse them and still point its errors at the YAML line.
#pragma once

#include <array>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/motion.hpp"

namespace kinegen::codegen {

// An expression as written in the file ("2.0", "omega*t", "x_crank - 1").
struct Expr {
  std::string text;
  SourceLoc loc;
};

// A vector of the file: [x, y], or in a spatial file [x, y, z] (z's text is empty in planar
// files).
struct Vec2 {
  Expr x, y;
  Expr z{};
};

struct Parameter {
  std::string name;
  Expr value;  // a constant, or an expression of earlier parameters (a derived parameter)
  SourceLoc loc;
};

// A named subexpression: coordinates, parameters, t and earlier definitions.
struct Definition {
  std::string name;
  Expr value;
  SourceLoc loc;
};

// A reported scalar: coordinates, t, parameters and definitions; its CSV columns
// are NAME, NAME.v and NAME.a.
struct Output {
  std::string name;
  Expr value;
  SourceLoc loc;
};

struct Body {
  std::string name;
  std::array<Expr, 3> q0;  // x, y, phi (planar files)
  SourceLoc loc;
  // A spatial file's guess of the body's pose (docs/format.md, Spatial mechanisms): the
  // frame's origin r0, and its orientation as Euler parameters p0 (from `p0` or `q0`, not yet
  // normalized), or else as the rotation `rot0` by `angle` about `axis` (default: none).
  struct Pose {
    std::array<Expr, 3> r0;
    std::vector<Expr> p0;  // e0, e1, e2, e3; empty: from axis and angle
    std::array<Expr, 3> axis;
    Expr angle;
    SourceLoc rotation_loc;  // of p0, q0 or rot0
  };
  Pose pose;
};

// An extra scalar unknown: a curve parameter, a contact angle. Follows the bodies'
// coordinates in q, in file order; expressions use it by its name.
struct Coordinate {
  std::string name;
  Expr q0;
  CoordinateKind kind = CoordinateKind::kScalar;
  SourceLoc loc;
};

// A registered joint or driver type (constraints/registry.hpp): its keys, equations and drawing.
struct ConstraintKind;

// A body reference: an index into Mechanism::bodies, or kGround.
inline constexpr int kGround = -1;

// A driver's law beyond one expression: pieces, a period, a table or a run-time
// input. With none of them the law is Constraint::value.
struct DriverPiece {
  Expr until;  // empty text for the last piece
  Expr f;
  SourceLoc loc;
};

class TableSlot;  // a registered table's slot (table.hpp)

struct DriverLaw {
  std::vector<DriverPiece> pieces;  // `f: [{until: T1, f: E1}, ..., {f: En}]`
  std::optional<Expr> period;       // `period: T`
  std::string table;                // `table: FILE.csv` (as written)
  SourceLoc table_loc;
  int table_id = -1;   // its fitted spline (table.hpp's registry)
  // Holds table_id's slot: the table lives as long as any copy of the mechanism using it.
  std::shared_ptr<const TableSlot> table_ref;
  bool input = false;  // `f: input`
  bool plain() const { return pieces.empty() && table_id < 0 && !input; }
};

// One joint or driver: its kind and the values of its keys, with the defaults the format
// promises filled in (s = [0, 0], angle = 0). Which keys there are is the kind's (KeySpec).
struct Constraint {
  const ConstraintKind* kind = nullptr;
  bool is_driver = false;
  std::string name;  // optional, a validated identifier; "" when not given
  std::string item;  // how messages name it: "joints[2] (revolute)"
  SourceLoc loc;
  int i = kGround;   // body i (or `body` for one-body types)
  int j = kGround;   // body j
  std::map<std::string, Vec2> vectors;  // local vectors by key: si, sj, s, vi
  std::map<std::string, Expr> scalars;  // other constants by key
  int joint = -1;  // a kJoint key (a spatial driver's `joint`): index into Mechanism::joints
  std::map<std::string, bool> flags;    // true/false keys (a gear's `internal`)
  Expr value;        // value / length / angle of a joint, or f(t) of a driver
  DriverLaw law;     // a driver's pieces, period, table or input
  std::vector<Expr> equations;  // expression constraints: each string = 0
  std::map<std::string, Vec2> curves;      // kCurve keys: [x(u), y(u)] local to a body
  std::map<std::string, int> coordinates;  // kCoordinate keys: index into Mechanism::coordinates
  // A free coordinate: listed under `free:`, kept among the drivers (after the file's
  // own) as an input driver whose value, rate and acceleration are the dynamics' state
  // z, zd and zdd. value0 and v0 are its state at t0 (value0 absent: its value at the
  // assembled q0).
  struct Free {
    std::optional<Expr> value0;
    Expr v0{"0", {}};
  };
  std::optional<Free> free;

  const char* type_name() const;
  // Number of scalar equations this constraint contributes.
  int equation_count() const;
  // A vector key of the kind (throws std::logic_error for a key the kind does not have).
  const Vec2& vector(const std::string& key) const;
};

struct Point {
  std::string name;
  int body = kGround;
  Vec2 s;
  SourceLoc loc;
};

// Mass data of one body (docs/format.md: Masses and `gravity`): all default to 0; mass and
// inertia (about the centre of mass) >= 0.
struct BodyMass {
  Expr mass{"0", {}}, inertia{"0", {}};
  Vec2 com{{"0", {}}, {"0", {}}};  // in the body's frame
  SourceLoc loc;
};

struct Load {
  enum class Kind { kForce, kTorque, kSpringDamper, kRotationalSpringDamper };
  Kind kind = Kind::kForce;
  std::string name;  // optional
  std::string item;  // "forces[2] (spring_damper)"
  SourceLoc loc;
  int body = kGround;     // force, torque
  int i = kGround, j = kGround;  // spring-dampers
  Vec2 s, si, sj;         // points (force: s; linear spring-damper: si, sj)
  Vec2 f;                 // force: global components
  Expr value;             // torque
  Expr stiffness, damping, length0, preload, angle0;
  // Components written `input` (docs/format.md: Load inputs): run-time inputs, like an input
  // driver's value. component: 0 and 1 a force's x and y, 2 a torque's value; name: the
  // load's name (a torque) or name_x / name_y (a force); index: its place among the
  // mechanism's load inputs (file order); table_id: the table `--input NAME=FILE.csv` gave it,
  // -1 while it is a run-time input.
  struct Input {
    int component = 0;
    std::string name;
    int index = 0;
    int table_id = -1;
    std::shared_ptr<const TableSlot> table_ref;  // holds table_id's slot (table.hpp)
  };
  std::vector<Input> inputs;
};

struct ForceSpec {
  std::vector<BodyMass> bodies;  // one per body (empty: all zero)
  Vec2 gravity{{"0", {}}, {"0", {}}};
  SourceLoc gravity_loc;
  std::vector<Load> loads;
};

// A spatial file's `suspension:` block (docs/format.md, Suspension analysis): one corner's
// parts, by name. The loader appends its outputs (toe ... track_change) to Mechanism::outputs,
// from `first_output` on; the analysis subtracts the design position's value from
// wheel_travel and track_change and adds a motion ratio column per spring.
struct Suspension {
  SourceLoc loc;
  int sigma = 1;  // +1 left, -1 right
  int upright = kGround;
  std::string wheel_center, spin_axis, steer_upper, steer_lower;  // points, a vector
  Expr tire_radius;
  Expr design_t{"0", {}};
  // Outputs (by index into Mechanism::outputs) whose value is a spring's length.
  std::vector<int> springs;
  int first_output = 0;  // toe; the others follow in the order of the table
};

struct Mechanism {
  // `space: 3d`: bodies have q = [x, y, z, e0, e1, e2, e3] (docs/format.md, Spatial mechanisms).
  bool spatial = false;
  SourceLoc space_loc;
  std::string name;
  SourceLoc name_loc;  // of the `name:` value
  std::string source;  // the file it was read from, as given by the user
  std::vector<Parameter> parameters;
  std::vector<Definition> definitions;
  std::vector<Body> bodies;
  std::vector<Coordinate> coordinates;  // extra unknowns, after the bodies' in q
  std::vector<Constraint> joints;
  std::vector<Constraint> drivers;
  std::vector<Point> points;
  std::vector<Point> vectors;  // spatial files: named vectors fixed in a body (Point::s)
  // Spatial files: one Euler parameter normalization row per body (`euler_<body>`), the
  // tool's own: after the drivers in Phi, and not counted among the joints.
  std::vector<Constraint> normalization;
  std::vector<Output> outputs;
  std::optional<Suspension> suspension;  // spatial files only
  ForceSpec forces;  // masses, gravity and loads (`analyze --forces`)
  // docs/format.md, `stop_when`: `simulate` ends where this crosses 0 from below.
  std::optional<Expr> stop_when;

  // Coordinates per body: x, y, phi; or x, y, z, e0, e1, e2, e3 in a spatial file.
  int body_coordinates() const { return spatial ? 7 : 3; }
  int nq() const {
    return body_coordinates() * static_cast<int>(bodies.size()) +
           static_cast<int>(coordinates.size());
  }
  // The index in q of extra coordinate k.
  int coordinate_index(int k) const {
    return body_coordinates() * static_cast<int>(bodies.size()) + k;
  }
  int nc() const;
  // Joints then drivers, in file order, then the normalization rows: the order of the rows
  // of Phi.
  std::vector<const Constraint*> constraints() const;
  std::optional<int> find_body(const std::string& name) const;
  // The free coordinates as indices into `drivers`, in `free:` order; they follow
  // the file's drivers there.
  std::vector<int> free_drivers() const;
  int num_free() const { return static_cast<int>(free_drivers().size()); }
  // The loads' inputs (Load::inputs), in file order.
  std::vector<const Load::Input*> load_inputs() const;
  // The slots of the run-time inputs' values (ProgramEvaluator::set_inputs): 3 per driver
  // (value, rate, acceleration), then 3 per load input (its value first).
  int input_slots() const {
    return 3 * (static_cast<int>(drivers.size()) + static_cast<int>(load_inputs().size()));
  }
};

// The run-time inputs u of the dynamics, in order: each input driver that is not
// free (f: input) as its value, rate and acceleration (named D, D_v, D_a, as a generated
// header's Params members), then each load input still without a table (Load::Input::name),
// with its slot in the inputs array.
struct RunInput {
  std::string name;
  int slot = 0;
};
std::vector<RunInput> run_inputs(const Mechanism& mechanism);

// Reads and validates a mechanism file. Throws InputError naming the file, item and line.
Mechanism load_mechanism(const std::string& path);
// The same from text in memory (`source` names it in messages).
Mechanism parse_mechanism(const std::string& yaml_text, const std::string& source);

// Every coordinate's name as the CSV's position columns give it, in q's order: each body's
// `B.x, B.y, B.phi` (spatial: `B.x, B.y, B.z, B.e0, B.e1, B.e2, B.e3`), then the extra
// coordinates by name.
std::vector<std::string> coordinate_labels(const Mechanism& mechanism);

// Whether `name` may become a C++ identifier in generated code: a C identifier, not a C++
// keyword, and not a reserved form (leading underscore, or "__" anywhere).
bool is_valid_identifier(const std::string& name);

}  // namespace kinegen::codegen
