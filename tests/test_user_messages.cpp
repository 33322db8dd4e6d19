// Messages a new user met (issue 26), each as one InputError or warning that says what to do:
// an output that uses a velocity's name (omega_rocker) says that outputs are functions of
// positions and time and names the position to use; a misspelt name gets the nearest one the
// expression may use; an unknown key's "expected:" list includes type and name where they are
// allowed, and a key no item takes (type on a body) is refused; a seam warning shows 0, not the
// rounding of the one-sided limit.
#include <catch2/catch.hpp>
#include <string>

#include "kinegen/codegen/analysis/compiled_model.hpp"
#include "kinegen/codegen/model/mechanism.hpp"

namespace {

namespace kc = kinegen::codegen;

// A four-bar with `joint_key` added to its first joint, `body_key` to its coupler, and the
// output w = `output` (none when empty).
std::string four_bar(const std::string& joint_key, const std::string& body_key,
                     const std::string& output) {
  return "name: fb\n"
         "parameters: {a: 1.0, b: 3.5, c: 2.5, d: 3.0}\n"
         "bodies:\n"
         "  - {name: crank, q0: [0, 0, 0]}\n"
         "  - {name: coupler, q0: [1, 0, 0.78]" +
         body_key +
         "}\n"
         "  - {name: rocker, q0: [3, 0, 1.37]}\n"
         "joints:\n"
         "  - {type: revolute, i: ground, j: crank" +
         joint_key +
         "}\n"
         "  - {type: revolute, i: crank, j: coupler, si: [a, 0]}\n"
         "  - {type: revolute, i: coupler, j: rocker, si: [b, 0], sj: [c, 0]}\n"
         "  - {type: revolute, i: ground, j: rocker, si: [d, 0]}\n"
         "drivers:\n"
         "  - {type: absolute_angle, body: crank, f: t}\n" +
         (output.empty() ? "" : "outputs:\n  w: \"" + output + "\"\n");
}

// The message of the InputError that compiling `text` raises.
std::string error_of(const std::string& text) {
  try {
    (void)kc::CompiledModel::from_mechanism(kc::parse_mechanism(text, "fb.yaml"));
  } catch (const kc::InputError& e) {
    return e.what();
  }
  FAIL("no InputError");
  return "";
}

}  // namespace

TEST_CASE("messages: an output in a velocity says outputs are of positions and time",
          "[user_messages]") {
  // The file loads as written with positions.
  CHECK_NOTHROW(kc::CompiledModel::from_mechanism(
      kc::parse_mechanism(four_bar("", "", "phi_rocker"), "fb.yaml")));
  for (const char* name : {"omega_rocker", "alpha_rocker", "phid_rocker"}) {
    CAPTURE(name);
    const std::string what = error_of(four_bar("", "", std::string("2*") + name));
    INFO(what);
    CHECK(what.find("outputs.w") != std::string::npos);
    CHECK(what.find("outputs are functions of positions and time") != std::string::npos);
    CHECK(what.find("'phi_rocker'") != std::string::npos);
    CHECK(what.find("NAME.v") != std::string::npos);
  }
  // A velocity of a length: vx_coupler is the rate of x_coupler.
  const std::string vx = error_of(four_bar("", "", "vx_coupler"));
  CHECK(vx.find("'x_coupler'") != std::string::npos);
  // A misspelt name: the nearest one the expression may use.
  const std::string typo = error_of(four_bar("", "", "phi_rocekr - phi_coupler"));
  INFO(typo);
  CHECK(typo.find("unknown symbol 'phi_rocekr'; did you mean 'phi_rocker'?") != std::string::npos);
  // Nothing near: no guess.
  const std::string far = error_of(four_bar("", "", "zebra"));
  CHECK(far.find("unknown symbol 'zebra'") != std::string::npos);
  CHECK(far.find("did you mean") == std::string::npos);
}

TEST_CASE("messages: the expected keys list type and name where an item takes them",
          "[user_messages]") {
  const std::string joint = error_of(four_bar(", color: red", "", ""));
  INFO(joint);
  CHECK(joint.find("unknown key 'color' (expected: type, ") != std::string::npos);
  CHECK(joint.find(", name") != std::string::npos);
  // A body has a name but no type: `type` there was silently ignored, now it is refused.
  const std::string body = error_of(four_bar("", ", type: link", ""));
  INFO(body);
  CHECK(body.find("unknown key 'type' (expected: name, q0") != std::string::npos);
}

TEST_CASE("messages: a seam warning shows a one-sided 0 as 0", "[user_messages]") {
  // The indexer's seam t = 4: the 3-4-5 rise ends with f'' = 0, the harmonic rise starts with
  // (pi/2) pi^2 / 2 = pi^3 / 4; taken a hair inside its piece the end read -1.4137166941154068e-23.
  const auto model = kc::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) +
                                                  "/tests/mechanisms/indexer.yaml");
  const auto& w = model->symbolic().warnings;
  REQUIRE(w.size() == 2);
  INFO(w[0] << "\n" << w[1]);
  CHECK(w[0].find("f'' jumps at the boundary t = 1: -7.75156917") != std::string::npos);
  CHECK(w[0].find("before it, 0 after it") != std::string::npos);
  CHECK(w[1].find("f'' jumps at the period's seam t = 4: 0 before it, 7.75156917") !=
        std::string::npos);
}
