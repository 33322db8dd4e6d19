// The registry of constraint types (constraints/registry.hpp): every registered type is exercised
// by tests/mechanisms/all_types.yaml (so the emitter's strict compile and `kinegen check` see it),
// the loader knows exactly the registered types, and row names reach the messages.
#include <catch2/catch.hpp>
#include <set>
#include <string>

#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/model/mechanism.hpp"

namespace {

namespace kc = kinegen::codegen;

TEST_CASE("every registered type appears in all_types.yaml wherever it may appear", "[registry]") {
  // Planar types in all_types.yaml, spatial ones in spatial_all_types.yaml (a type name
  // resolves by the file's space).
  for (const bool spatial : {false, true}) {
    const kc::Mechanism m = kc::load_mechanism(std::string(KINEGEN_SOURCE_DIR) +
                                               "/tests/mechanisms/" +
                                               (spatial ? "spatial_all_types" : "all_types") +
                                               ".yaml");
    std::set<std::string> joints, drivers;
    for (const auto& c : m.joints) joints.insert(c.type_name());
    for (const auto& c : m.drivers) drivers.insert(c.type_name());
    std::set<std::string> names;
    for (const kc::ConstraintKind* k : kc::constraint_kinds()) {
      if (!k->in_space(spatial)) continue;
      INFO(k->name << (spatial ? " (spatial)" : ""));
      CHECK(names.insert(k->name).second);  // names are unique within a space
      CHECK(k->equations != nullptr);
      if (k->rows != 1) CHECK(k->row_name != nullptr);  // several rows are named in messages
      // The Euler parameters' normalization is the tool's own row, never in a file.
      if (std::string(k->name) == "euler_parameters") {
        CHECK((!k->joint && !k->driver));
        continue;
      }
      CHECK((k->joint || k->driver));
      if (k->joint) CHECK(joints.count(k->name) == 1);
      if (k->driver) CHECK(drivers.count(k->name) == 1);
    }
    // Nothing in the file is outside the registry.
    for (const auto& n : joints) CHECK(kc::find_constraint_kind(n, spatial) != nullptr);
    for (const auto& n : drivers) CHECK(kc::find_constraint_kind(n, spatial) != nullptr);
  }
}

TEST_CASE("the loader lists the registered types in its message", "[registry]") {
  const std::string yaml =
      "name: m\nbodies:\n  - name: a\n    q0: [0, 0, 0]\njoints:\n  - type: hinge\n"
      "    i: ground\n    j: a\n";
  try {
    kc::parse_mechanism(yaml, "m.yaml");
    FAIL("an unknown type was accepted");
  } catch (const kc::InputError& e) {
    const std::string what = e.what();
    for (const kc::ConstraintKind* k : kc::constraint_kinds())
      if (k->joint && k->in_space(false)) CHECK(what.find(k->name) != std::string::npos);
  }
}

TEST_CASE("row labels name the row of a constraint with several", "[registry]") {
  const std::string yaml =
      "name: m\nbodies:\n  - name: a\n    q0: [0, 0, 0]\njoints:\n  - type: revolute\n"
      "    i: ground\n    j: a\ndrivers:\n  - type: absolute_angle\n    body: a\n    f: t\n";
  const auto model = kc::CompiledModel::from_mechanism(kc::parse_mechanism(yaml, "m.yaml"));
  CHECK(model->row_label(0) == "joints[0] (revolute) x-component (line 6)");
  CHECK(model->row_label(1) == "joints[0] (revolute) y-component (line 6)");
  CHECK(model->row_label(2) == "drivers[0] (absolute_angle) (line 10)");
}

}  // namespace
