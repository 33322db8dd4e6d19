// Hostile and malformed mechanism files (issue 4, item 5), end to end: every case gives exactly
// one `error:` line naming the file, the item and the YAML line, exit status 2, and neither
// `generate -o DIR` nor `analyze -o FILE` leaves any file behind.
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "support/files.hpp"
#include "support/run_command.hpp"

namespace {

namespace fs = std::filesystem;
using kinegen::test::write_text;
namespace kc = kinegen::codegen;
using kinegen::test::CommandResult;

// A valid slider-crank; each case below changes one thing in it.
const std::string kBase = R"(name: m
parameters:
  l: 2.0
bodies:
  - name: crank
    q0: [0, 0, 0]
  - name: rod
    q0: [2, 0, 0]
joints:
  - type: revolute
    i: ground
    j: crank
  - type: revolute
    i: crank
    j: rod
    si: [1, 0]
    sj: ["-l", 0]
  - type: absolute_y
    body: rod
    value: 0
drivers:
  - type: absolute_angle
    body: crank
    f: "t"
)";

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  REQUIRE(at != std::string::npos);
  return text.replace(at, from.size(), to);
}

struct Case {
  const char* name;
  std::string text;
  const char* item;     // the item the message must name
  int line;             // the YAML line it must name (0: none)
  const char* message;  // a phrase of the message
};

std::vector<Case> cases() {
  const std::string& b = kBase;
  return {
      {"unknown_symbol", replaced(b, "\"t\"", "\"t*w\""), "drivers[0] (absolute_angle) f", 24,
       "unknown symbol 'w'"},
      {"division_by_zero", replaced(b, "\"-l\"", "\"1/0\""), "joints[1] (revolute) sj", 17,
       "division by zero"},
      {"division_by_zero_symbolic", replaced(b, "\"-l\"", "\"1/(l-l)\""), "joints[1] (revolute) sj",
       17, "division by zero"},
      {"division_by_zero_in_driver", replaced(b, "\"t\"", "\"t/(l-2)\""),
       "drivers[0] (absolute_angle) f", 24, "division by zero"},
      {"nan", replaced(b, "q0: [2, 0, 0]", "q0: [.nan, 0, 0]"), "body 'rod'", 8,
       "'.nan' is not a finite number"},
      {"inf", replaced(b, "q0: [2, 0, 0]", "q0: [-.inf, 0, 0]"), "body 'rod'", 8,
       "'-.inf' is not a finite number"},
      {"huge_decimal", replaced(b, "l: 2.0", "l: 1e999"), "parameters.l", 3, "not a finite number"},
      {"huge_decimal_in_driver", replaced(b, "\"t\"", "\"1e999*t\""),
       "drivers[0] (absolute_angle) f", 24, "not finite"},
      {"vector_too_long", replaced(b, "si: [1, 0]", "si: [1, 0, 0]"), "joints[1] (revolute) si", 16,
       "vector of 2 numbers"},
      {"q0_too_short", replaced(b, "q0: [2, 0, 0]", "q0: [2, 0]"), "body 'rod'", 8, "3 numbers"},
      {"duplicate_body", replaced(b, "name: rod", "name: crank"), "body 'crank'", 7,
       "duplicate body name"},
      {"body_named_ground", replaced(b, "name: rod", "name: ground"), "bodies[1]", 7, "'ground'"},
      {"unknown_joint_type", replaced(b, "type: absolute_y", "type: prismatic"), "joints[2]", 18,
       "unknown joint type 'prismatic'"},
      {"yaml_syntax", replaced(b, "q0: [2, 0, 0]", "q0: [2, 0, 0"), "YAML syntax", 9, ""},
      {"expression_syntax", replaced(b, "\"t\"", "\"t*(2\""), "drivers[0] (absolute_angle) f", 24,
       "expected ')'"},
      {"cpp_keyword", replaced(b, "name: rod", "name: class"), "bodies[1]", 7, "not a valid name"},
      {"reserved_underscore_capital", replaced(b, "name: rod", "name: _Rod"), "bodies[1]", 7,
       "not a valid name"},
      {"reserved_double_underscore", replaced(b, "name: rod", "name: a__b"), "bodies[1]", 7,
       "not a valid name"},
      {"keyword_mechanism_name", replaced(b, "name: m\n", "name: int\n"), "name", 1,
       "not a valid name"},
      {"name_with_line_break", replaced(b, "name: m\n", "name: \"m\\n#include <x>\"\n"), "name", 1,
       "not a valid name"},
      {"name_with_comment_close", replaced(b, "name: rod", "name: \"rod*/\""), "bodies[1]", 7,
       "not a valid name"},
      {"expression_too_long", replaced(b, "\"t\"", "\"t" + std::string(5000, '+') + "t\""),
       "drivers[0] (absolute_angle) f", 24, "longer than"},
      {"expression_too_deep",
       replaced(b, "\"t\"", "\"" + std::string(100, '(') + "t" + std::string(100, ')') + "\""),
       "drivers[0] (absolute_angle) f", 24, "nests parentheses"},
      {"empty_file", "", "file", 0, "empty"},
      // GiNaC differentiates b^e through log(b): 0^l has a pole there. It was an "internal
      // error" with exit 1 (the fuzzer's find).
      {"zero_to_a_parameter", replaced(b, "\"-l\"", "\"-l + 0^l\""), "joints[1] (revolute)", 13,
       "cannot be differentiated"},
  };
}

fs::path scratch(const std::string& name) { return kinegen::test::scratch_dir("hostile", name); }

CommandResult run_kinegen(std::vector<std::string> args) {
  args.insert(args.begin(), KINEGEN_EXE);
  return kinegen::test::run_command(args);
}

// One error line: "error: FILE[:LINE]: ITEM: MESSAGE".
void check_error(const CommandResult& r, const fs::path& file, const Case& c) {
  INFO("stderr: " << r.err);
  CHECK(r.exit_code == 2);
  REQUIRE(r.err.rfind("error: ", 0) == 0);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  const std::string where = file.string() + (c.line > 0 ? ":" + std::to_string(c.line) : "");
  CHECK(r.err.rfind("error: " + where + ": " + c.item, 0) == 0);
  CHECK(r.err.find(c.message) != std::string::npos);
  CHECK(r.out.empty());
}

}  // namespace

TEST_CASE("the base mechanism of the hostile-input cases is valid", "[hostile]") {
  const fs::path dir = scratch("base");
  write_text(dir / "m.yaml", kBase);
  const auto r = run_kinegen({"analyze", (dir / "m.yaml").string(), "--t0", "0", "--t1", "1",
                              "--steps", "2", "-o", (dir / "m.csv").string()});
  CHECK(r.exit_code == 0);
  CHECK(fs::exists(dir / "m.csv"));
}

TEST_CASE("every malformed file gives one error line, exit 2 and no output", "[hostile]") {
  for (const Case& c : cases()) {
    SECTION(c.name) {
      const fs::path dir = scratch(c.name);
      const fs::path mech = dir / "mech.yaml";
      write_text(mech, c.text);
      const fs::path out = dir / "out";
      fs::create_directories(out);
      check_error(run_kinegen({"generate", mech.string(), "-o", out.string()}), mech, c);
      check_error(run_kinegen({"analyze", mech.string(), "--t0", "0", "--t1", "1", "--steps", "2",
                               "-o", (out / "m.csv").string()}),
                  mech, c);
      check_error(run_kinegen({"eval", mech.string()}), mech, c);
      CHECK(fs::is_empty(out));
      // The library says the same with the item and line as data.
      try {
        (void)kc::load_mechanism(mech.string());
      } catch (const kc::InputError& e) {
        CHECK(e.item().rfind(c.item, 0) == 0);
        CHECK(e.loc().line == c.line);
      }
    }
  }
}

TEST_CASE("an under-driven mechanism cannot be analyzed (exit 2, no output)", "[hostile]") {
  const fs::path dir = scratch("under_driven");
  const fs::path mech = dir / "mech.yaml";
  write_text(
      mech,
      replaced(kBase, "drivers:\n  - type: absolute_angle\n    body: crank\n    f: \"t\"\n", ""));
  const fs::path csv = dir / "out.csv";
  const auto r = run_kinegen(
      {"analyze", mech.string(), "--t0", "0", "--t1", "1", "--steps", "2", "-o", csv.string()});
  INFO(r.err);
  CHECK(r.exit_code == 2);
  CHECK(r.err.rfind("error: " + mech.string() + ": drivers: ", 0) == 0);
  CHECK(r.err.find("not kinematically driven") != std::string::npos);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  CHECK_FALSE(fs::exists(csv));
  CHECK_FALSE(fs::exists(dir / "loose.svg"));
}

TEST_CASE("a missing file is one error line naming it, exit 2, no output", "[hostile]") {
  const fs::path dir = scratch("missing");
  const fs::path mech = dir / "nowhere.yaml";
  for (const auto& args :
       std::vector<std::vector<std::string>>{{"generate", mech.string(), "-o", dir.string()},
                                             {"analyze", mech.string(), "--t0", "0", "--t1", "1",
                                              "--steps", "1", "-o", (dir / "x.csv").string()}}) {
    const auto r = run_kinegen(args);
    CHECK(r.exit_code == 2);
    CHECK(r.err == "error: " + mech.string() +
                       ": file: cannot open the mechanism file: No such file or directory\n");
  }
  CHECK(fs::is_empty(dir));
}

TEST_CASE("a file name never reaches the generated header raw", "[hostile]") {
  const fs::path dir = scratch("file_name");
  const fs::path mech = dir / "evil\n#error injected.yaml";
  write_text(mech, kBase);
  const auto r = run_kinegen({"generate", mech.string(), "-o", dir.string()});
  REQUIRE(r.exit_code == 0);
  std::ifstream in(dir / "m.hpp");
  std::stringstream text;
  text << in.rdbuf();
  // The name is in the banner, its line break made harmless: no directive comes of it.
  CHECK(text.str().find("injected") != std::string::npos);
  CHECK(text.str().find("\n#error") == std::string::npos);
}

TEST_CASE("a file above the size limit is refused before parsing", "[hostile]") {
  const std::string big = kBase + "# " + std::string(2 << 20, 'x') + "\n";
  try {
    (void)kc::parse_mechanism(big, "big.yaml");
    FAIL("accepted");
  } catch (const kc::InputError& e) {
    CHECK(e.item() == "file");
    CHECK(std::string(e.what()).find("larger than") != std::string::npos);
  }
}

TEST_CASE("bodies and nothing else: the commands that solve name the undriven body",
          "[hostile]") {
  // The fuzzer's find: Eigen's SVD of Phi_q with no rows read past an empty matrix, and
  // `analyze` of this file ended in a segmentation fault.
  const fs::path dir = scratch("bodies_only");
  const fs::path mech = dir / "loose.yaml", csv = dir / "loose.csv";
  write_text(mech, "name: loose\nbodies:\n  - {name: a, q0: [0, 0, 0]}\n");
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"analyze", mech.string(), "--t0", "0", "--t1", "1", "--steps",
                                 "2", "-o", csv.string()},
        std::vector<std::string>{"animate", mech.string(), "--t0", "0", "--t1", "1", "--steps",
                                 "2", "-o", (dir / "loose.svg").string()},
        std::vector<std::string>{"tolerance", mech.string(), "--tol", "x=1", "--t0", "0", "--t1",
                                 "1", "--steps", "2"}}) {
    const auto r = run_kinegen(args);
    INFO(args[0] << ": " << r.err);
    CHECK(r.exit_code == 2);
    CHECK(r.err.rfind("error: ", 0) == 0);
    CHECK(r.err.find("not kinematically driven") != std::string::npos);
    CHECK(r.err.find("body 'a'") != std::string::npos);
  }
  CHECK_FALSE(fs::exists(csv));
  CHECK_FALSE(fs::exists(dir / "loose.svg"));
}

// GiNaC differentiates b^e through log(b), so 0^a has a pole there. Where the second
// derivatives of the dynamics (equilibrium, modes, linearize, a header's Jacobians) or a
// damper's rates meet one, the message names the body or the load and its line; both were
// "internal error", exit 1.
TEST_CASE("a pole met in the dynamics' derivatives names the item (exit 2)", "[hostile]") {
  const std::string pendulum = kinegen::test::read_text(
      std::string(KINEGEN_SOURCE_DIR) + "/examples/dynamics/pendulum.yaml");
  const fs::path dir = scratch("dynamics_pole");
  const fs::path com = dir / "com.yaml", damper = dir / "damper.yaml";
  write_text(com, replaced(pendulum, "com: [a, 0]", "com: [\"a + 0^g\", 0]"));
  write_text(damper, replaced(pendulum, "gravity: [0, -g]",
                              "gravity: [0, -g]\nforces:\n  - {type: spring_damper, name: d, i: "
                              "ground, j: rod, si: [\"0^a\", 0], sj: [0, 0], stiffness: 0, "
                              "damping: 1, length0: 0}"));
  const auto one_error = [](const CommandResult& r, const std::string& start,
                            const char* phrase) {
    INFO(r.err);
    CHECK(r.exit_code == 2);
    CHECK(r.err.rfind("error: " + start, 0) == 0);
    CHECK(r.err.find(phrase) != std::string::npos);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  };
  for (const char* command : {"linearize", "modes", "equilibrium"})
    one_error(run_kinegen({command, com.string(), "-q"}), com.string() + ":9: body 'rod'",
              "second derivatives cannot be formed");
  const fs::path out = dir / "out";
  fs::create_directories(out);
  one_error(run_kinegen({"generate", com.string(), "-o", out.string()}),
            com.string() + ":9: body 'rod'", "second derivatives cannot be formed");
  CHECK(fs::is_empty(out));
  const auto gravity = pendulum.begin() + static_cast<long>(pendulum.find("gravity:"));
  const int line = 3 + static_cast<int>(std::count(pendulum.begin(), gravity, '\n'));  // 2 below
  one_error(run_kinegen({"simulate", damper.string(), "--t1", "0.1", "--steps", "2", "-q"}),
            damper.string() + ":" + std::to_string(line) + ": forces[0] 'd' (spring_damper)",
            "its rates cannot be formed");
}

// Two items that derive the same Params member (issue 35, item 6): a free `x` (x, x_v, x_a)
// beside a free `x_a`; a free `x_x` beside a force `x` whose x component is an input (x_x);
// a free `push_x` beside a force `push` (push_x). Each header redeclared the member and did
// not compile, after `generate` had exited 0. The refusal names both items, before any file
// is written; the cart-pole as it is still generates a header that compiles.
TEST_CASE("generate refuses two items that derive the same Params member", "[hostile]") {
  const std::string cart_pole = kinegen::test::read_text(std::string(KINEGEN_SOURCE_DIR) +
                                                         "/examples/dynamics/cart_pole.yaml");
  const std::string x = "name: x, body: cart", phi = "name: phi, body: pole",
                    push = "name: push, body: cart";
  struct Clash {
    const char* name;
    std::string text;
    const char* first;   // the item that declares the member first (free items come before loads)
    const char* second;  // the item refused
    const char* member;
  };
  const std::vector<Clash> clashes = {
      {"free_x_and_x_a", replaced(cart_pole, phi, "name: x_a, body: pole"), "free[0] 'x'",
       "free[1] 'x_a'", "x_a"},
      {"free_x_x_and_force_x",
       replaced(replaced(cart_pole, x, "name: x_x, body: cart"), push, "name: x, body: cart"),
       "free[0] 'x_x'", "forces[0] 'x'", "x_x"},
      {"free_push_x_and_force_push", replaced(cart_pole, x, "name: push_x, body: cart"),
       "free[0] 'push_x'", "forces[0] 'push'", "push_x"},
  };
  for (const Clash& c : clashes) {
    SECTION(c.name) {
      const fs::path dir = scratch(c.name);
      const fs::path mech = dir / "cart_pole.yaml", out = dir / "out";
      write_text(mech, c.text);
      fs::create_directories(out);
      const auto r = run_kinegen({"generate", mech.string(), "-o", out.string()});
      INFO(r.err);
      CHECK(r.exit_code == 2);
      CHECK(r.err.rfind("error: " + mech.string() + ":", 0) == 0);
      CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
      CHECK(r.err.find(c.first) != std::string::npos);
      CHECK(r.err.find(c.second) != std::string::npos);
      CHECK(r.err.find("'" + std::string(c.member) + "'") != std::string::npos);
      CHECK(fs::is_empty(out));
    }
  }
  SECTION("no clash: the header compiles") {
    const fs::path dir = scratch("no_clash");
    const fs::path mech = dir / "cart_pole.yaml";
    // x, x_v, x_a and xa, xa_v, xa_a, push_x: near the clashes above, all distinct.
    write_text(mech, replaced(cart_pole, phi, "name: xa, body: pole"));
    REQUIRE(run_kinegen({"generate", mech.string(), "-o", dir.string()}).exit_code == 0);
    write_text(dir / "use.cpp",
               "#include \"cart_pole.hpp\"\n"
               "int main() {\n"
               "  kinegen::models::cart_pole::Params p;\n"
               "  p.x_a = 1; p.xa = 2; p.xa_a = 3; p.push_x = 4;\n"
               "  return p.x_a + p.xa + p.xa_a + p.push_x == 10 ? 0 : 1;\n"
               "}\n");
    const auto cc = kinegen::test::run_command({KINEGEN_CXX, "-std=c++17", "-fsyntax-only", "-I",
                                                dir.string(), (dir / "use.cpp").string()});
    INFO(cc.err);
    CHECK(cc.exit_code == 0);
  }
}
