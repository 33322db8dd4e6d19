// Loader (loader.hpp): the forces: section (docs/format.md: Masses, gravity and loads).
#include <algorithm>
#include <cctype>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_set>
#include <vector>

#include "loader.hpp"

namespace kinegen::codegen::model_detail {

// Applied loads (docs/format.md: Loads), with their defaults: s, si, sj [0, 0]; damping 0;
// rotational angle0 0.
void Loader::read_forces(const YAML::Node& node, Mechanism& m) {
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
      {"spring_damper",
       Load::Kind::kSpringDamper,
       {"i", "j", "stiffness", "length0"},
       {"si", "sj", "damping", "preload"}},
      {"rotational_spring_damper",
       Load::Kind::kRotationalSpringDamper,
       {"i", "j", "stiffness"},
       {"damping", "angle0"}},
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
    std::vector<std::string> required = kind->required, optional = kind->optional;
    required.insert(required.begin(), "type");
    optional.insert(optional.begin(), "name");
    check_keys(f, item, required, optional);
    const Expr zero{"0", load.loc};
    load.s = load.si = load.sj = Vec2{zero, zero};
    load.damping = load.preload = load.angle0 = zero;
    if (f["body"]) load.body = body_ref(f["body"], m, item, false);
    if (f["i"]) load.i = body_ref(f["i"], m, item, true);
    if (f["j"]) load.j = body_ref(f["j"], m, item, true);
    if (f["i"] && load.i == load.j) fail(item, loc_of(f["j"]), "i and j must be different bodies");
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
    read_load_inputs(load, m);
    m.forces.loads.push_back(std::move(load));
  }
}

// A force's component or a torque's value written `input` is a run-time input, named
// after the load: the torque's name, or name_x / name_y for a force's components.
void Loader::read_load_inputs(Load& load, const Mechanism& m) {
  const std::pair<const Expr*, int> components[] = {
      {&load.f.x, 0}, {&load.f.y, 1}, {&load.value, 2}};
  int count = 0;
  for (const Load& l : m.forces.loads) count += static_cast<int>(l.inputs.size());
  for (const auto& [e, component] : components) {
    if (e->text != "input") continue;
    if (load.kind != Load::Kind::kForce && load.kind != Load::Kind::kTorque) continue;
    if (load.name.empty())
      fail(load.item, e->loc,
           "a run-time input needs the load's `name` (the input is named after it)");
    Load::Input in;
    in.component = component;
    in.name = component == 2 ? load.name : load.name + (component == 0 ? "_x" : "_y");
    in.index = count++;
    for (const Parameter& prm : m.parameters)
      if (prm.name == in.name)
        fail(load.item, e->loc, "the input '" + in.name + "' is named like a parameter");
    for (const Constraint& d : m.drivers)
      if (d.name == in.name || d.name + "_v" == in.name || d.name + "_a" == in.name)
        fail(load.item, e->loc, "the input '" + in.name + "' is named like " + d.item + "'s");
    for (const Load& l : m.forces.loads)
      for (const Load::Input& other : l.inputs)
        if (other.name == in.name)
          fail(load.item, e->loc, "the input '" + in.name + "' is also " + l.item + "'s");
    load.inputs.push_back(in);
  }
}

}  // namespace kinegen::codegen::model_detail
