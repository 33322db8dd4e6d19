// The command line under hostile use (issue 13, items 9 to 14), end to end on the kinegen
// executable: output files that planted links, devices, full disks and signals cannot harm;
// exact arithmetic and derivatives of bounded cost; names the generated header cannot carry;
// meaningless options refused; messages that say what is wrong.
#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <catch2/catch.hpp>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "kinegen/codegen/emit/reserved_names.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "support/files.hpp"
#include "support/run_command.hpp"

namespace {

namespace fs = std::filesystem;
namespace kc = kinegen::codegen;
using kinegen::test::CommandResult;

fs::path example(const std::string& name) {
  return fs::path(KINEGEN_SOURCE_DIR) / "examples" / (name + ".yaml");
}

fs::path scratch_dir(const std::string& name) {
  return kinegen::test::scratch_dir("cli_safety", name);
}

using kinegen::test::read_text;
using kinegen::test::write_text;

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  REQUIRE(at != std::string::npos);
  return text.replace(at, from.size(), to);
}

std::vector<std::string> entries(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename());
  std::sort(names.begin(), names.end());
  return names;
}

CommandResult run_kinegen(const std::vector<std::string>& args) {
  std::vector<std::string> argv{KINEGEN_EXE};
  argv.insert(argv.end(), args.begin(), args.end());
  return kinegen::test::run_command(argv);
}

void require_one_error_line(const CommandResult& r) {
  INFO("stderr: " << r.err);
  REQUIRE(r.err.rfind("error: ", 0) == 0);
  REQUIRE(std::count(r.err.begin(), r.err.end(), '\n') == 1);
}

// A kinegen child process (support/run_command.hpp: ChildProcess) with standard input from
// /dev/null and standard output sent to `out_path`.
struct Child : kinegen::test::ChildProcess {
  fs::path err_path;

  Child(const std::vector<std::string>& args, const std::string& out_path, const fs::path& err,
        rlim_t cpu_seconds = 0, rlim_t address_bytes = 0)
      : ChildProcess(with_exe(args), "/dev/null", out_path, err.string(), cpu_seconds,
                     address_bytes),
        err_path(err) {}
  static std::vector<std::string> with_exe(const std::vector<std::string>& args) {
    std::vector<std::string> full{KINEGEN_EXE};
    full.insert(full.end(), args.begin(), args.end());
    return full;
  }
  std::string err() const { return read_text(err_path); }
};

CommandResult run_to(const std::vector<std::string>& args, const std::string& out_path,
                     const fs::path& dir, rlim_t cpu = 0, rlim_t bytes = 0) {
  Child child(args, out_path, dir / "stderr.txt", cpu, bytes);
  CommandResult r;
  r.exit_code = child.wait();
  r.err = child.err();
  return r;
}

bool is_root() { return ::geteuid() == 0; }

// A four-bar whose every q0 is zero: its first solve fails (nothing solved, exit 1).
std::string failing_four_bar() {
  std::string text = read_text(example("four_bar"));
  text = std::regex_replace(text, std::regex(R"(q0: \[[^\]]*\])"), "q0: [0, 0, 0]");
  return text;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Item 9: temporary files are exclusive and never follow links; a failed or interrupted run
// leaves the target as it was; devices and pipes are written in place, never replaced.

TEST_CASE("item 9: links planted at the temporary name and at the target are never followed",
          "[cli-safety]") {
  const fs::path dir = scratch_dir("links");
  const fs::path victim = dir / "victim.txt", victim_temp = dir / "victim_temp.txt";
  write_text(victim, "precious\n");
  write_text(victim_temp, "precious too\n");
  const fs::path target = dir / "out.csv";
  fs::create_symlink(victim, target);
  // The old writer's temporary name was FILE.tmp-kinegen-<pid>: plant a link at it for the
  // pids the next processes will get.
  long last = 0;
  std::ifstream("/proc/sys/kernel/ns_last_pid") >> last;
  long pid_max = 32768;
  std::ifstream("/proc/sys/kernel/pid_max") >> pid_max;
  for (long p = last + 1; p <= last + 3000; ++p)
    fs::create_symlink(victim_temp, dir / ("out.csv.tmp-kinegen-" + std::to_string(p % pid_max)));

  // A failed analysis (nothing solved) leaves everything as it was.
  const fs::path bad = dir / "bad.yaml";
  write_text(bad, failing_four_bar());
  auto r = run_kinegen(
      {"analyze", bad.string(), "--t0", "0", "--t1", "1", "--steps", "2", "-o", target.string()});
  CHECK(r.exit_code == 1);
  CHECK(read_text(victim) == "precious\n");
  CHECK(read_text(victim_temp) == "precious too\n");
  CHECK(fs::is_symlink(target));

  // A successful one replaces the link at the target by a regular file, following nothing.
  r = run_kinegen({"analyze", example("four_bar").string(), "--t0", "0", "--t1", "1", "--steps",
                   "4", "-o", target.string()});
  INFO(r.err);
  CHECK(r.exit_code == 0);
  CHECK(read_text(victim) == "precious\n");
  CHECK(read_text(victim_temp) == "precious too\n");
  CHECK_FALSE(fs::is_symlink(target));
  CHECK(fs::is_regular_file(target));
  CHECK(read_text(target).rfind("t,", 0) == 0);
  // generate and animate write the same way.
  const fs::path header = dir / "four_bar.hpp";
  fs::create_symlink(victim, header);
  r = run_kinegen({"generate", example("four_bar").string(), "-o", dir.string(), "-q"});
  CHECK(r.exit_code == 0);
  CHECK(read_text(victim) == "precious\n");
  CHECK(fs::is_regular_file(fs::symlink_status(header)));
  // No temporary file is left behind.
  for (const auto& name : entries(dir)) CHECK(name.find(".kinegen-") == std::string::npos);
}

TEST_CASE("item 9: a pipe and a device node are written in place, never replaced", "[cli-safety]") {
  const fs::path dir = scratch_dir("devices");
  const fs::path fifo = dir / "out.fifo";
  REQUIRE(::mkfifo(fifo.c_str(), 0644) == 0);
  // Both ends held open here, so neither kinegen's open nor a read blocks; the CSV fits in the
  // pipe's buffer.
  const int read_end = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK);
  REQUIRE(read_end >= 0);
  const int write_end = ::open(fifo.c_str(), O_WRONLY);
  REQUIRE(write_end >= 0);
  const auto r = run_kinegen({"analyze", example("four_bar").string(), "--t0", "0", "--t1", "1",
                              "--steps", "4", "-o", fifo.string()});
  ::close(write_end);
  std::string received;
  char buf[4096];
  for (ssize_t n; (n = ::read(read_end, buf, sizeof buf)) > 0;) received.append(buf, n);
  ::close(read_end);
  CHECK(r.exit_code == 0);
  CHECK(fs::is_fifo(fs::symlink_status(fifo)));
  CHECK(received.rfind("t,", 0) == 0);

  if (is_root()) {
    // A device node of our own (a copy of /dev/null): it stays a device.
    const fs::path null_dev = dir / "null";
    REQUIRE(::mknod(null_dev.c_str(), S_IFCHR | 0666, makedev(1, 3)) == 0);
    const auto r2 = run_kinegen({"analyze", example("four_bar").string(), "--t0", "0", "--t1", "1",
                                 "--steps", "4", "-o", null_dev.string()});
    CHECK(r2.exit_code == 0);
    CHECK(fs::is_character_file(fs::symlink_status(null_dev)));
    // -o /dev/stdout writes to standard output and leaves /dev/stdout as it was.
    const bool was_link = fs::is_symlink("/dev/stdout");
    const auto r3 = run_kinegen({"analyze", example("four_bar").string(), "--t0", "0", "--t1", "1",
                                 "--steps", "4", "-o", "/dev/stdout"});
    const bool replaced_node = was_link && !fs::is_symlink("/dev/stdout");
    if (replaced_node) {  // a regression must not leave the machine without /dev/stdout
      fs::remove("/dev/stdout");
      fs::create_symlink("/proc/self/fd/1", "/dev/stdout");
    }
    CHECK_FALSE(replaced_node);
    CHECK(r3.exit_code == 0);
    CHECK(r3.out.rfind("t,", 0) == 0);
    CHECK(fs::is_symlink("/dev/stdout") == was_link);
    CHECK_FALSE(fs::is_regular_file(fs::symlink_status("/dev/stdout")));
  }
}

// SIGINT stops a run at its next row instead, keeping the rows (test_hostile_use.cpp, item 3).
TEST_CASE("item 9: an interrupted run removes its temporary file and keeps the target",
          "[cli-safety]") {
  for (int sig : {SIGTERM, SIGHUP}) {
    const fs::path dir = scratch_dir("interrupted_" + std::to_string(sig));
    const fs::path target = dir / "out.csv";
    write_text(target, "old\n");
    // Long enough to be interrupted while it writes.
    Child child({"analyze", example("four_bar").string(), "--t0", "0", "--t1", "1e4", "--steps",
                 "20000000", "-o", target.string()},
                "/dev/null", dir.parent_path() / ("stderr_" + std::to_string(sig) + ".txt"));
    bool saw_temp = false;
    for (int k = 0; k < 3000 && !saw_temp; ++k) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      saw_temp = entries(dir).size() > 1;
    }
    CHECK(saw_temp);
    ::kill(child.pid, sig);
    const int status = child.wait();
    CHECK(status == 128 + sig);
    CHECK(entries(dir) == std::vector<std::string>{"out.csv"});
    CHECK(read_text(target) == "old\n");
  }
}

// ---------------------------------------------------------------------------------------------
// Item 10: a write error on a file or on standard output is exit 1 with an error line.

TEST_CASE("item 10: writing to a full device fails with exit 1 and one error line",
          "[cli-safety]") {
  const fs::path dir = scratch_dir("full");
  const std::string mech = example("four_bar").string();
  const std::vector<std::vector<std::string>> commands = {
      {"analyze", mech, "--t0", "0", "--t1", "1", "--steps", "10"},
      {"eval", mech},
      {"check", mech, "--samples", "1"}};
  for (const auto& args : commands) {
    const auto r = run_to(args, "/dev/full", dir);
    INFO(args[0] << ": " << r.err);
    CHECK(r.exit_code == 1);
    require_one_error_line(r);
    CHECK(r.err.find("No space left on device") != std::string::npos);
  }
  for (const auto& args : {std::vector<std::string>{"analyze", mech, "--t0", "0", "--t1", "1",
                                                    "--steps", "10", "-o", "/dev/full"},
                           std::vector<std::string>{"animate", mech, "--t0", "0", "--t1", "1",
                                                    "--steps", "4", "-o", "/dev/full"}}) {
    const auto r = run_kinegen(args);
    INFO(args[0] << " -o /dev/full: " << r.err);
    CHECK(r.exit_code == 1);
    require_one_error_line(r);
  }
}

// ---------------------------------------------------------------------------------------------
// Item 11: exact numbers and derivatives of bounded cost, refused before the work.

TEST_CASE("item 11: costly exact powers and derivative growth are refused at their line",
          "[cli-safety]") {
  const fs::path dir = scratch_dir("cost");
  std::string product;
  for (int k = 1; product.size() < 3950; ++k)
    product += (product.empty() ? "" : "*") + ("sin(" + std::to_string(k) + "*t)");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"2^(2^40)*0+t", "exponent"},
      {"t*10^(10^9)*10^(-(10^9))", "exponent"},
      {"t*(10^999)^100", "digits"},
      {"t*1e9999", "limit of exact numbers"},
      {product, "derivatives"}};
  const std::string base = read_text(example("four_bar"));
  for (const auto& [f, phrase] : cases) {
    const fs::path mech = dir / "m.yaml";
    write_text(mech, replaced(base, "f: \"omega*t\"", "f: \"" + f + "\""));
    for (const char* command : {"eval", "generate"}) {
      // 20 s of CPU and 1 GiB: the old code aborted in GMP or ran for a minute here.
      std::vector<std::string> args{command, mech.string()};
      if (std::string(command) == "generate") args.insert(args.end(), {"-o", dir.string()});
      const auto r = run_to(args, "/dev/null", dir, 20, rlim_t(1) << 30);
      INFO(command << " f = " << f.substr(0, 60) << ": " << r.err);
      CHECK(r.exit_code == 2);
      require_one_error_line(r);
      CHECK(r.err.find("m.yaml:53: drivers[0] (absolute_angle)") != std::string::npos);
      CHECK(r.err.find(phrase) != std::string::npos);
    }
  }
  // A parameter's value is bounded where it is used: a^p with p = 2^40.
  const fs::path mech = dir / "p.yaml";
  write_text(mech, replaced(base, "si: [\"b\", 0]", "si: [\"b*2^a/2^(a-1)/2\", 0]"));
  const auto r =
      run_to({"eval", mech.string(), "--param", "a=2^40"}, "/dev/null", dir, 20, rlim_t(1) << 30);
  INFO(r.err);
  CHECK(r.exit_code == 2);
  CHECK(r.err.find("exponent") != std::string::npos);
  // generate expands equations to find the linear ones: (y + 1 + p1 + ... + p5 + l)^40 would
  // have 7e7 terms (the old code ran out of memory there).
  std::string slider = read_text(example("slider_crank"));
  slider = replaced(slider, "  omega: 1.0      # crank angular speed [rad/s]\n",
                    "  omega: 1.0\n  p1: 0.1\n  p2: 0.1\n  p3: 0.1\n  p4: 0.1\n  p5: 0.1\n");
  slider = replaced(slider,
                    "  - type: absolute_y        # slider runs on the global x axis\n"
                    "    body: rod\n    value: 0",
                    "  - type: expression\n    equations: [\"(y_rod + 1 + p1 + p2 + p3 + p4 + p5 + "
                    "l)^40 - (1 + p1 + p2 + p3 + p4 + p5 + l)^40\"]");
  write_text(mech, slider);
  const auto g = run_to({"generate", mech.string(), "-o", dir.string()}, "/dev/null", dir, 20,
                        rlim_t(1) << 30);
  INFO(g.err);
  CHECK(g.exit_code == 2);
  CHECK(g.err.find("p.yaml:38: joints[2] (expression): expanded") != std::string::npos);
  // The same rule for every command: analyze's block solver expands the same equations.
  for (const char* command : {"analyze", "eval"}) {
    std::vector<std::string> args = {command, mech.string()};
    if (std::string(command) == "analyze")
      args.insert(args.end(), {"--t0", "0", "--t1", "1", "--steps", "2"});
    const auto r2 = run_to(args, "/dev/null", dir, 20, rlim_t(1) << 30);
    INFO(command << ": " << r2.err);
    CHECK(r2.exit_code == 2);
    CHECK(r2.err.find("p.yaml:38: joints[2] (expression): expanded") != std::string::npos);
  }
  // With the parameters folded the equation is (y_rod + c)^40 - c^40: 41 terms, generated.
  const auto folded = run_to({"generate", mech.string(), "-o", dir.string(), "--fold-params"},
                             "/dev/null", dir, 20, rlim_t(1) << 30);
  INFO(folded.err);
  CHECK(folded.exit_code == 0);
  // Ordinary powers still work.
  write_text(mech, replaced(base, "f: \"omega*t\"", "f: \"omega*t + 0.001*sin(t)^3*2^(1/3)\""));
  CHECK(run_kinegen({"eval", mech.string()}).exit_code == 0);
}

// ---------------------------------------------------------------------------------------------
// Item 12: names the header cannot carry are refused by generate alone; --namespace separates
// two models of the same name.

TEST_CASE(
    "item 12: generate refuses names that break the header; analyze, eval, check accept "
    "them",
    "[cli-safety]") {
  const fs::path dir = scratch_dir("names");
  const std::string base = read_text(example("four_bar"));
  struct Case {
    std::string from, to;
    const char* item;
    int line;
  };
  std::vector<Case> cases;
  for (const char* n : {"std", "phi", "gamma", "nq", "q0", "length_scale", "solve_position",
                        "BlockOptions", "BlockReport", "linux", "unix", "Params"})
    cases.push_back({"name: four_bar", std::string("name: ") + n, "name", 13});
  for (const char* n : {"M_PI", "M_E", "NAN", "INFINITY", "HUGE_VAL", "FP_NAN", "EOF", "errno"})
    cases.push_back({"  omega: 1.0", std::string("  ") + n + ": 1.0", nullptr, 21});
  for (const auto& c : cases) {
    std::string text = replaced(base, c.from, c.to);
    if (!c.item)
      text =
          replaced(text, "f: \"omega*t\"", "f: \"" + c.to.substr(2, c.to.find(':') - 2) + "*t\"");
    const fs::path mech = dir / "m.yaml";
    write_text(mech, text);
    const fs::path out = dir / "out";
    fs::remove_all(out);
    auto r = run_kinegen({"generate", mech.string(), "-o", out.string()});
    INFO(c.to << ": " << r.err);
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
    const std::string item = c.item ? c.item : "parameters." + c.to.substr(2, c.to.find(':') - 2);
    CHECK(r.err.find("m.yaml:" + std::to_string(c.line) + ": " + item + ": ") != std::string::npos);
    CHECK((!fs::exists(out) || fs::is_empty(out)));
    CHECK(run_kinegen({"eval", mech.string()}).exit_code == 0);
    CHECK(run_kinegen({"analyze", mech.string(), "--t0", "0", "--t1", "1", "--steps", "2"})
              .exit_code == 0);
  }
}

TEST_CASE(
    "item 12: every name the emitter declares in the struct, and every macro of the "
    "standard headers, is refused",
    "[cli-safety]") {
  // Declarations at struct scope (two-space indent) in every committed header and in a
  // rolled, split one: static members, nested types, helpers.
  std::vector<fs::path> headers;
  for (const auto& e : fs::directory_iterator(fs::path(KINEGEN_SOURCE_DIR) / "generated"))
    headers.push_back(e.path());
  const fs::path dir = scratch_dir("members");
  REQUIRE(run_kinegen(
              {"generate",
               (fs::path(KINEGEN_SOURCE_DIR) / "tests/mechanisms/fourbar_chain_3.yaml").string(),
               "-o", dir.string(), "-q", "--roll-min", "2", "--max-function-ops", "8"})
              .exit_code == 0);
  // Headers with the kinetostatics and the outputs, whose members the examples lack.
  for (const char* mech : {"examples/forces/press.yaml", "tests/mechanisms/four_bar_outputs.yaml"})
    REQUIRE(run_kinegen({"generate", (fs::path(KINEGEN_SOURCE_DIR) / mech).string(), "-o",
                         dir.string(), "-q"})
                .exit_code == 0);
  for (const auto& e : fs::directory_iterator(dir)) headers.push_back(e.path());
  const std::regex decl(
      R"(^  (?:static |template <[^>]*> static |struct |using |enum (?:class )?)(?:[\w:<>, ]*?[\s*&])?([A-Za-z]\w*)\s*(?:[({=;\[]|$))");
  std::set<std::string> declared;
  for (const auto& h : headers) {
    std::istringstream in(read_text(h));
    for (std::string line; std::getline(in, line);) {
      std::smatch m;
      if (std::regex_search(line, m, decl)) declared.insert(m[1]);
    }
  }
  CHECK(declared.size() > 25);
  for (const auto& name : declared) {
    INFO("declared at struct scope: " << name);
    CHECK_FALSE(kc::header_name_conflict(name, kc::HeaderName::kModel).empty());
  }
  // Every macro the compiler defines after the standard headers, in GNU and strict modes.
  const fs::path tu = dir / "all.cpp";
  write_text(tu,
             "#include <algorithm>\n#include <array>\n#include <atomic>\n#include <cassert>\n"
             "#include <cerrno>\n#include <cfenv>\n#include <cfloat>\n#include <cinttypes>\n"
             "#include <climits>\n#include <clocale>\n#include <cmath>\n#include <complex>\n"
             "#include <csetjmp>\n#include <csignal>\n#include <cstdarg>\n#include <cstdint>\n"
             "#include <cstdio>\n#include <cstdlib>\n#include <cstring>\n#include <ctime>\n"
             "#include <cwchar>\n#include <cwctype>\n#include <iostream>\n#include <thread>\n"
             "#include <utility>\n#include <vector>\n");
  for (const char* std_flag : {"-std=gnu++17", "-std=c++17", "-std=c++20"}) {
    const auto r = kinegen::test::run_command({KINEGEN_CXX, std_flag, "-dM", "-E", tu.string()});
    REQUIRE(r.exit_code == 0);
    std::istringstream in(r.out);
    int macros = 0;
    for (std::string line; std::getline(in, line);) {
      std::istringstream words(line);
      std::string define, name;
      words >> define >> name;
      name = name.substr(0, name.find('('));
      if (name.empty() || !kc::is_valid_identifier(name)) continue;
      ++macros;
      INFO(std_flag << ": macro " << name);
      CHECK_FALSE(kc::header_name_conflict(name, kc::HeaderName::kParameter).empty());
    }
    CHECK(macros > 100);
  }
}

TEST_CASE("item 12: generate --namespace lets two models of the same name share a program",
          "[cli-safety]") {
  const fs::path dir = scratch_dir("namespace");
  const std::string base = read_text(example("four_bar"));
  // Two different mechanisms, both named twin: crank 1.0 and 1.5.
  write_text(dir / "a.yaml", replaced(base, "name: four_bar", "name: twin"));
  write_text(dir / "b.yaml", replaced(replaced(base, "name: four_bar", "name: twin"),
                                      "  a: 1.0          # crank", "  a: 1.5"));
  fs::create_directories(dir / "a");
  fs::create_directories(dir / "b");
  REQUIRE(run_kinegen({"generate", (dir / "a.yaml").string(), "-o", (dir / "a").string(),
                       "--namespace", "plant::left"})
              .exit_code == 0);
  REQUIRE(run_kinegen({"generate", (dir / "b.yaml").string(), "-o", (dir / "b").string(),
                       "--namespace", "plant::right"})
              .exit_code == 0);
  write_text(
      dir / "tu_a.cpp",
      "#include \"a/twin.hpp\"\ndouble left_a() { return plant::left::twin::Params{}.a; }\n");
  write_text(
      dir / "tu_b.cpp",
      "#include \"b/twin.hpp\"\ndouble right_a() { return plant::right::twin::Params{}.a; }\n");
  write_text(dir / "main.cpp",
             "double left_a();\ndouble right_a();\n"
             "int main() { return left_a() == 1.0 && right_a() == 1.5 ? 0 : 1; }\n");
  const std::string exe = (dir / "twins").string();
  const auto cc = kinegen::test::run_command(
      {KINEGEN_CXX, "-std=c++17", "-O0", "-I", dir.string(), (dir / "tu_a.cpp").string(),
       (dir / "tu_b.cpp").string(), (dir / "main.cpp").string(), "-o", exe});
  INFO(cc.err);
  REQUIRE(cc.exit_code == 0);
  CHECK(kinegen::test::run_command({exe}).exit_code == 0);
  // A namespace that is not one is a usage error.
  for (const char* bad : {"std", "a::", "1x", "a::class", "M_PI", "a b"}) {
    const auto r = run_kinegen(
        {"generate", (dir / "a.yaml").string(), "-o", dir.string(), "--namespace", bad});
    INFO(bad << ": " << r.err);
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
  }
}

// ---------------------------------------------------------------------------------------------
// Item 13: check --turns beyond what its bounds can mean is a usage error.

TEST_CASE("item 13: check --turns 1e300 is a usage error; 1e6 turns still checks", "[cli-safety]") {
  const std::string mech = example("four_bar").string();
  for (const char* turns : {"1e300", "-1e300", "1e8"}) {
    const auto r = run_kinegen({"check", mech, "--turns", turns});
    INFO(turns << ": " << r.err);
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
    CHECK(r.err.find("--turns") != std::string::npos);
  }
  CHECK(run_kinegen({"check", mech, "--turns", "1e6"}).exit_code == 0);
}

// ---------------------------------------------------------------------------------------------
// Item 14: messages that say what is wrong.

TEST_CASE("item 14: messages name q0, the contradiction, the free bodies and the option",
          "[cli-safety]") {
  const fs::path dir = scratch_dir("messages");
  const std::string four_bar = read_text(example("four_bar"));
  const auto analyze = [&](const std::string& text, std::vector<std::string> extra = {}) {
    write_text(dir / "m.yaml", text);
    std::vector<std::string> args{
        "analyze", (dir / "m.yaml").string(), "--t0", "0", "--t1", "1", "--steps", "2", "-q"};
    args.insert(args.end(), extra.begin(), extra.end());
    return run_kinegen(args);
  };
  {  // all-zero q0
    const auto r = analyze(failing_four_bar());
    INFO(r.err);
    CHECK(r.exit_code == 1);
    require_one_error_line(r);
    CHECK(r.err.find("q0") != std::string::npos);
  }
  {  // a redundant model slightly off: the third crank 1e-3 too long
    const std::string dp =
        read_text(fs::path(KINEGEN_SOURCE_DIR) / "tests/stability/double_parallelogram.yaml");
    const auto r = analyze(replaced(dp, "name: A3, i: crank3, j: coupler, si: [1, 0]",
                                    "name: A3, i: crank3, j: coupler, si: [1.001, 0]"));
    INFO(r.err);
    CHECK(r.exit_code == 1);
    CHECK(r.err.find("constraints are not satisfied") != std::string::npos);
  }
  {  // a forgotten ground pivot
    const auto at = four_bar.find("  - type: revolute          # O4");
    const auto end = four_bar.find("drivers:");
    const auto r = analyze(four_bar.substr(0, at) + four_bar.substr(end));
    INFO(r.err);
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
    CHECK(r.err.find("'coupler'") != std::string::npos);
    CHECK(r.err.find("'rocker'") != std::string::npos);
    CHECK(r.err.find("'crank'") == std::string::npos);
    CHECK(r.err.find(": drivers: ") == std::string::npos);
  }
  {  // --param a=1e999 blames the option
    const auto r = analyze(four_bar, {"--param", "a=1e999"});
    INFO(r.err);
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
    CHECK(r.err.find("--param a") != std::string::npos);
    CHECK(r.err.find("parameters.a") == std::string::npos);
    CHECK(r.err.find(":15:") == std::string::npos);
  }
  for (const char* v : {".nan", "-.inf", "nan"}) {  // no GiNaC internals
    const auto r = analyze(four_bar, {"--param", std::string("a=") + v});
    INFO(r.err);
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
    CHECK(r.err.find("--param a") != std::string::npos);
    CHECK(r.err.find("not a finite number") != std::string::npos);
    CHECK(r.err.find("e0_") == std::string::npos);
  }
  {  // 2^2^2
    const auto r = analyze(replaced(four_bar, "f: \"omega*t\"", "f: \"2^2^2*t\""));
    INFO(r.err);
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
    CHECK(r.err.find("make_binop_expr") == std::string::npos);
    CHECK(r.err.find("(a^b)^c or a^(b^c)") != std::string::npos);
    CHECK(r.err.find(":53:") != std::string::npos);
  }
  {  // --t0 -1e308 --t1 1e308
    write_text(dir / "m.yaml", four_bar);
    const auto r = run_kinegen(
        {"analyze", (dir / "m.yaml").string(), "--t0", "-1e308", "--t1", "1e308", "--steps", "3"});
    INFO(r.err);
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
    CHECK(r.err.find("nan") == std::string::npos);
    CHECK(r.out.empty());
  }
  for (const char* d : {"inf", "nan", "-1"}) {  // animate --duration
    const fs::path svg = dir / "a.svg";
    const auto r = run_kinegen({"animate", example("four_bar").string(), "--t0", "0", "--t1", "1",
                                "--steps", "4", "--duration", d, "-o", svg.string()});
    INFO(d << ": " << r.err);
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
    CHECK(r.err.find("--duration") != std::string::npos);
    CHECK_FALSE(fs::exists(svg));
  }
}
