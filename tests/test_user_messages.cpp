// Messages a new user met (issue 26), each as one InputError or warning that says what to do:
// an output that spells a velocity otherwise (omega_rocker) is given the format's name
// (phid_rocker) and an acceleration's name (alpha_rocker) is refused naming the velocity; a
// misspelt name gets the nearest one the expression may use; an unknown key's "expected:" list
// includes type and name where they are allowed, and a key no item takes (type on a body) is
// refused; a seam warning shows 0, not the rounding of the one-sided limit.
#include <catch2/catch.hpp>
#include <filesystem>
#include <string>

#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "support/files.hpp"
#include "support/run_command.hpp"

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

TEST_CASE("messages: an output's velocity by another name is given the format's name",
          "[user_messages]") {
  // The file loads as written with positions, and with velocities (as loads may use them).
  CHECK_NOTHROW(kc::CompiledModel::from_mechanism(
      kc::parse_mechanism(four_bar("", "", "phi_rocker"), "fb.yaml")));
  CHECK_NOTHROW(kc::CompiledModel::from_mechanism(
      kc::parse_mechanism(four_bar("", "", "2*phid_rocker"), "fb.yaml")));
  for (const char* name : {"omega_rocker", "alpha_rocker"}) {
    CAPTURE(name);
    const std::string what = error_of(four_bar("", "", std::string("2*") + name));
    INFO(what);
    CHECK(what.find("outputs.w") != std::string::npos);
    CHECK(what.find("'phi_rocker'") != std::string::npos);
    CHECK(what.find("velocity is 'phid_rocker'") != std::string::npos);
    CHECK((what.find("an acceleration of") != std::string::npos) ==
          (std::string(name) == "alpha_rocker"));
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

namespace {

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  REQUIRE(at != std::string::npos);
  return text.replace(at, from.size(), to);
}

// The one `error:` line of `kinegen simulate` on `text` (exit 2), 0.1 s of motion.
std::string simulate_error(const std::string& name, const std::string& text) {
  const auto dir = kinegen::test::scratch_dir("user_messages", name);
  const auto yaml = dir / (name + ".yaml");
  kinegen::test::write_text(yaml, text);
  const auto r =
      kinegen::test::run_command({KINEGEN_EXE, "simulate", yaml.string(), "--t1", "0.1", "--steps",
                                  "1", "-q", "-o", (dir / "out.csv").string()});
  INFO(r.err);
  CHECK(r.exit_code == 2);
  CHECK(r.err.rfind("error: " + yaml.string() + ":", 0) == 0);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  return r.err;
}

}  // namespace

// Issue 36, item 7: a name used above its definition says where it is defined; it was an
// "unknown symbol" that sent the user looking for a typo.
TEST_CASE("messages: a parameter or definition used before its definition says where",
          "[user_messages]") {
  std::string text = four_bar("", "", "");
  text = replaced(text, "parameters: {a: 1.0, b: 3.5, c: 2.5, d: 3.0}\n",
                  "parameters:\n  a: 1.0\n  b: \"c + 1\"\n  c: 2.5\n  d: 3.0\n");
  // b is on line 4, c on line 5.
  const std::string later = error_of(text);
  INFO(later);
  CHECK(later.find("parameters.b") != std::string::npos);
  CHECK(later.find("c is defined at line 5, after its use at line 4") != std::string::npos);
  // A definition that reads a later one.
  const std::string defs = replaced(four_bar("", "", ""), "bodies:\n",
                                    "definitions:\n  u: \"v + 1\"\n  v: \"2*a\"\nbodies:\n");
  const std::string def = error_of(defs);
  INFO(def);
  CHECK(def.find("definitions.u") != std::string::npos);
  CHECK(def.find("v is defined at line 5, after its use at line 4") != std::string::npos);
  // A real typo keeps its hint.
  const std::string typo = error_of(replaced(text, "\"c + 1\"", "\"cc + 1\""));
  CHECK(typo.find("unknown symbol 'cc'") != std::string::npos);
}

TEST_CASE("messages: a YAML syntax error quotes its line", "[user_messages]") {
  // Each error quotes the line it names, whichever line the parser reports (none when that
  // is the end of the file).
  int quoted_lines = 0;
  for (const std::string& text :
       {std::string("name: fb\nbodies:\n  - {name: a, q0: [0, 0, 0]\n  - b\njoints: []\n"),
        std::string("name: fb\nbodies:\n  - name: a\n   q0: [0, 0, 0]\n"),
        std::string("name: fb\nbodies: [}\njoints: []\n")}) {
    try {
      (void)kc::parse_mechanism(text, "fb.yaml");
      FAIL("accepted");
    } catch (const kc::InputError& e) {
      INFO(e.what());
      CHECK(e.item() == "YAML syntax");
      const int line = e.loc().line;
      REQUIRE(line >= 1);
      std::size_t begin = 0;
      for (int k = 1; k < line && begin < text.size(); ++k) begin = text.find('\n', begin) + 1;
      const std::string quoted =
          begin < text.size() ? text.substr(begin, text.find('\n', begin) - begin) : "";
      if (quoted.empty()) {
        CHECK(std::string(e.what()).find("in the line") == std::string::npos);
        continue;
      }
      ++quoted_lines;
      CHECK(std::string(e.what()).find("in the line: \"" + quoted + "\"") != std::string::npos);
    }
  }
  CHECK(quoted_lines >= 2);
  // The parser notices a missing ']' lines later: the line that opened it is quoted too.
  try {
    (void)kc::parse_mechanism(
        "name: fb\n# it's [ a comment\nbodies:\n  - name: \"a[\"\n    q0: [2, 0, 0\njoints: []\n",
        "fb.yaml");
    FAIL("accepted");
  } catch (const kc::InputError& e) {
    INFO(e.what());
    CHECK(std::string(e.what()).find("the '[' opened at line 5 is not closed: \"    q0: [2, 0, "
                                     "0\"") != std::string::npos);
  }
}

TEST_CASE("messages: a name longer than 64 characters says the limit", "[user_messages]") {
  const std::string long_name(65, 'r');
  const std::string what =
      error_of(replaced(four_bar("", "", ""), "name: rocker", "name: " + long_name));
  INFO(what);
  CHECK(what.find("65 characters long") != std::string::npos);
  CHECK(what.find("at most 64") != std::string::npos);
  // 64 is a name (the body's, every use of it renamed).
  std::string text = four_bar("", "", "");
  for (std::size_t at = text.find("rocker"); at != std::string::npos; at = text.find("rocker", at))
    text.replace(at, 6, std::string(64, 'r'));
  CHECK_NOTHROW(kc::parse_mechanism(text, "fb.yaml"));
}

namespace {

// A cart on a rail beside the crank-rocker of four_bar_damped: two free items, the cart's x
// first, each moving mass of its own.
std::string cart_and_four_bar() {
  std::string t = kinegen::test::read_text(std::string(KINEGEN_SOURCE_DIR) +
                                           "/examples/dynamics/four_bar_damped.yaml");
  t = replaced(t, "bodies:\n",
               "bodies:\n  - {name: cart, q0: [0, 0, 0], mass: cm, inertia: 0.01}\n");
  t = replaced(t, "joints:\n",
               "joints:\n  - {type: translational, name: rail, i: ground, j: cart, vi: [1, 0]}\n");
  t = replaced(t, "  theta0: 0 ", "  cm: 2.0\n  theta0: 0 ");
  return replaced(t, "free:\n",
                  "free:\n  - {type: absolute_x, name: x, body: cart, value0: 0.5}\n");
}

}  // namespace

// Issue 36, item 7 and issue 35, item 15: the free item that moves no mass is the only one
// named (the list named every free item), and the value0 that cannot be reached is blamed on
// its own item (it was the first free item with a value0).
TEST_CASE("messages: dynamics' start names the free item at fault", "[user_messages]") {
  const std::string base = cart_and_four_bar();
  {
    // The four-bar without mass: theta moves none, x moves the cart.
    std::string t = base;
    for (const char* mass : {"mass: 0.4", "mass: 1.2", "mass: 0.9"})
      t = replaced(t, mass, "mass: 0");
    for (const char* inertia : {"inertia: 0.0004", "inertia: 0.012", "inertia: 0.005"})
      t = replaced(t, inertia, "inertia: 0");
    const std::string err = simulate_error("massless", t);
    CHECK(err.find("free[1] 'theta'") != std::string::npos);
    CHECK(err.find("free[0] 'x'") == std::string::npos);
    CHECK(err.find("moves no mass") != std::string::npos);
  }
  {
    // The rocker swings between about 1.5 and 2.6 rad: never at 3. The cart's 0.5 is fine.
    const std::string t = replaced(
        base, "  - {type: absolute_angle, name: theta, body: crank, value0: theta0, v0: 0}",
        "  - {type: absolute_angle, name: psi, body: rocker, value0: 3, v0: 0}");
    const std::string err = simulate_error("unreachable", t);
    CHECK(err.find("free[1] 'psi' (absolute_angle) value0") != std::string::npos);
    CHECK(err.find("free[0] 'x' (absolute_x) value0") == std::string::npos);
    CHECK(err.find("does not assemble") != std::string::npos);
  }
  // Both items as they are: the mechanism runs.
  const auto dir = kinegen::test::scratch_dir("user_messages", "cart_and_four_bar");
  kinegen::test::write_text(dir / "ok.yaml", base);
  const auto r =
      kinegen::test::run_command({KINEGEN_EXE, "simulate", (dir / "ok.yaml").string(), "--t1",
                                  "0.1", "--steps", "1", "-q", "-o", (dir / "out.csv").string()});
  INFO(r.err);
  CHECK(r.exit_code == 0);
}
