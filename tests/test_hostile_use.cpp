// Issue 28: the command line and the library under hostile use. Threads (the generator library
// under its one lock from eight threads; generated Solvers in eight threads without one),
// Ctrl-C keeping the rows written, bounded reads of devices, FIFOs and standard input, bounded
// memory for a huge --steps, overflow-safe tolerance statistics, the jump test at the local
// scale, and messages that name their cause. The Python side (threads, KeyboardInterrupt, the
// same limits) is python/tests/test_threads.py.
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <kinegen/block_solver.hpp>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "four_bar.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/check.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/analysis/tolerance.hpp"
#include "kinegen/codegen/base/interrupt.hpp"
#include "kinegen/codegen/base/library_lock.hpp"
#include "kinegen/codegen/base/read_file.hpp"
#include "kinegen/codegen/emit/emit_cpp.hpp"
#include "pieces_drive.hpp"
#include "support/files.hpp"
#include "support/run_command.hpp"

namespace {

namespace fs = std::filesystem;
namespace kc = kinegen::codegen;
using kinegen::test::CommandResult;

std::string source(const std::string& path) { return std::string(KINEGEN_SOURCE_DIR) + "/" + path; }

fs::path scratch_dir(const std::string& name) {
  return kinegen::test::scratch_dir("hostile_use", name);
}

using kinegen::test::read_text;
using kinegen::test::write_text;

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

CommandResult run_kinegen(const std::vector<std::string>& args) {
  std::vector<std::string> argv{KINEGEN_EXE};
  argv.insert(argv.end(), args.begin(), args.end());
  return kinegen::test::run_command(argv);
}

// kinegen with stdin from `in`, bounded to 20 s of CPU and 1 GiB: the old code ran out of
// memory (bad_alloc, exit 1) or for minutes where these fail.
CommandResult run_bounded(const std::vector<std::string>& args, const fs::path& dir,
                          const std::string& in = "/dev/null") {
  std::vector<std::string> argv{KINEGEN_EXE};
  argv.insert(argv.end(), args.begin(), args.end());
  const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  fs::remove(out);
  kinegen::test::ChildProcess child(argv, in, out.string(), err.string(), 20, rlim_t{1} << 30);
  CommandResult r;
  r.exit_code = child.wait();
  r.out = read_text(out);
  r.err = read_text(err);
  return r;
}

void require_one_error_line(const CommandResult& r) {
  INFO("stderr: " << r.err);
  REQUIRE(r.err.rfind("error: ", 0) == 0);
  REQUIRE(std::count(r.err.begin(), r.err.end(), '\n') == 1);
}

std::unique_ptr<kc::CompiledModel> model_of(const fs::path& dir, const std::string& yaml,
                                            const std::vector<kc::ParamOverride>& params = {}) {
  const fs::path path = dir / "m.yaml";
  write_text(path, yaml);
  return kc::CompiledModel::from_file(path.string(), params);
}

// A slider along x driven by `f` (a YAML flow value), held on the x axis.
std::string slider(const std::string& f) {
  return "name: slide\nbodies:\n  - {name: s, q0: [0, 0, 0]}\njoints:\n"
         "  - {type: absolute_y, body: s, value: 0}\n"
         "  - {type: absolute_angle, body: s, value: 0}\n"
         "drivers:\n  - type: absolute_x\n    name: lift\n    body: s\n    " +
         f + "\n";
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Item 1: threads. The generator library is not thread-safe (GiNaC, CLN); under its one lock
// (base/library_lock.hpp), which the Python module takes in every method, eight threads mix
// every operation. The sanitizer pass runs this under AddressSanitizer.

TEST_CASE("item 1: eight threads load, analyze, check, generate and eval under the lock",
          "[hostile-use]") {
  const std::vector<std::string> files = {source("examples/slider_crank.yaml"),
                                          source("examples/gears/steering.yaml"),
                                          source("tests/mechanisms/pieces_drive.yaml")};
  // The answers of one thread alone, to compare with.
  std::vector<double> alone(files.size());
  for (std::size_t f = 0; f < files.size(); ++f) {
    kc::BuildOptions build;
    build.inputs_required = false;
    const auto m = kc::CompiledModel::from_file(files[f], {}, build);
    alone[f] = kc::evaluate(*m, m->q0(), Eigen::VectorXd::Zero(m->nq()), 0.3).phi.norm();
  }
  std::atomic<int> done{0}, wrong{0};
  std::vector<std::thread> threads;
  for (int k = 0; k < 8; ++k)
    threads.emplace_back([&, k] {
      const std::string& file = files[k % files.size()];
      std::unique_ptr<kc::CompiledModel> m;
      {
        std::lock_guard<std::recursive_mutex> lock(kc::library_mutex());
        kc::BuildOptions build;
        build.inputs_required = false;
        m = kc::CompiledModel::from_file(file, {}, build);
      }
      for (int op = 0; op < 4; ++op) {
        std::lock_guard<std::recursive_mutex> lock(kc::library_mutex());
        switch ((op + k) % 4) {
          case 0: {  // a mechanism with an input driver is not analysed without its table
            if (m->mechanism().drivers.size() == 3) break;
            int rows = 0;
            kc::run_analysis(*m, {0, 0.2, 4}, [&](const kc::StateRow&) { ++rows; });
            if (rows != 5) ++wrong;
            break;
          }
          case 1: {
            kc::CheckOptions o;
            o.samples = 1;
            o.digits = 20;
            for (const auto& r : kc::check_derivatives(*m, o))
              if (!r.ok()) ++wrong;
            break;
          }
          case 2:
            if (kc::emit_header(*m).empty())
              ++wrong;
            break;
          default: {
            const double v =
                kc::evaluate(*m, m->q0(), Eigen::VectorXd::Zero(m->nq()), 0.3).phi.norm();
            if (v != alone[k % files.size()]) ++wrong;
          }
        }
      }
      std::lock_guard<std::recursive_mutex> lock(kc::library_mutex());
      m.reset();  // a CompiledModel's GiNaC expressions are released under the lock too
      ++done;
    });
  for (auto& t : threads) t.join();
  CHECK(done == 8);
  CHECK(wrong == 0);
}

// Generated headers and kinegen::Solver share no state (no static or global data): eight
// threads, each with its own Solver and Params, give the bits one thread gives, without a lock.
template <class Model>
std::vector<double> solver_run(double scale, int steps) {
  typename Model::Params p;
  if constexpr (std::is_same_v<Model, kinegen::models::four_bar>) p.omega = scale;
  kinegen::Solver<Model> solver(p);
  typename kinegen::Solver<Model>::Vector q = solver.initial_estimate(), qd, qdd;
  qd.setZero();
  qdd.setZero();
  std::vector<double> out;
  for (int k = 0; k <= steps; ++k) {
    if (!solver.step(0.001 * k, q, qd, qdd)) return {};
    for (int c = 0; c < Model::nq; ++c) out.insert(out.end(), {q[c], qd[c], qdd[c]});
  }
  return out;
}

TEST_CASE("item 1: generated Solvers in eight threads give one thread's bits", "[hostile-use]") {
  const int steps = 2000;
  std::vector<std::vector<double>> want(8), got(8);
  for (int k = 0; k < 8; ++k)
    want[k] = k % 2 ? solver_run<kinegen::models::pieces_drive>(1, steps)
                    : solver_run<kinegen::models::four_bar>(1 + 0.1 * k, steps);
  std::vector<std::thread> threads;
  for (int k = 0; k < 8; ++k)
    threads.emplace_back([&, k] {
      got[k] = k % 2 ? solver_run<kinegen::models::pieces_drive>(1, steps)
                     : solver_run<kinegen::models::four_bar>(1 + 0.1 * k, steps);
    });
  for (auto& t : threads) t.join();
  for (int k = 0; k < 8; ++k) {
    INFO("thread " << k);
    REQUIRE_FALSE(want[k].empty());
    REQUIRE(got[k].size() == want[k].size());
    CHECK(std::memcmp(got[k].data(), want[k].data(), want[k].size() * sizeof(double)) == 0);
  }
}

// ---------------------------------------------------------------------------------------------
// Item 3: Ctrl-C. The library's interruption points stop a run; the command line keeps the rows
// written so far and says so (exit 130).

TEST_CASE("item 3: an interruption point stops run_analysis at the next row", "[hostile-use]") {
  const auto m = kc::CompiledModel::from_file(source("examples/four_bar.yaml"));
  int rows = 0;
  kc::ScopedInterruptHook hook([&] {
    if (rows == 10) throw kc::Interrupted("stop");
  });
  CHECK_THROWS_AS(kc::run_analysis(*m, {0, 1, 1000}, [&](const kc::StateRow&) { ++rows; }),
                  kc::Interrupted);
  CHECK(rows == 10);
}

TEST_CASE("item 3: SIGINT stops analyze and simulate, keeping the rows written (exit 130)",
          "[hostile-use]") {
  struct Case {
    std::vector<std::string> args;
  };
  const std::vector<Case> cases = {{{"analyze", source("examples/four_bar.yaml"), "--t0", "0",
                                     "--t1", "1e4", "--steps", "20000000"}},
                                   {{"simulate", source("examples/dynamics/pendulum.yaml"), "--t1",
                                     "1e6", "--steps", "20000000"}}};
  for (const auto& c : cases) {
    const fs::path dir = scratch_dir("sigint_" + c.args[0]);
    const fs::path target = dir / "out.csv";
    write_text(target, "old\n");
    std::vector<std::string> argv{KINEGEN_EXE};
    argv.insert(argv.end(), c.args.begin(), c.args.end());
    argv.insert(argv.end(), {"-o", target.string()});
    const fs::path err = dir.parent_path() / ("stderr_" + c.args[0] + ".txt");
    kinegen::test::ChildProcess child(argv, "/dev/null", "/dev/null", err.string());
    // Wait until it writes rows (its temporary file beside the target grows).
    bool writing = false;
    for (int k = 0; k < 3000 && !writing; ++k) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      for (const auto& e : fs::directory_iterator(dir))
        writing = writing || (e.path() != target && fs::file_size(e.path()) > 4096);
    }
    REQUIRE(writing);
    const auto sent = std::chrono::steady_clock::now();
    ::kill(child.pid, SIGINT);
    const int status = child.wait();
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - sent).count();
    const std::string message = read_text(err);
    INFO(c.args[0] << ": " << message);
    WARN(c.args[0] << ": stopped " << seconds * 1e3 << " ms after SIGINT");
    CHECK(status == 130);
    CHECK(seconds < 5);  // the old code died at once by the signal, keeping nothing
    CHECK(contains(message, "interrupted (SIGINT) after "));
    CHECK(contains(message, "; they are kept"));
    // The rows so far are in the target, as the message counts them, and no temporary file.
    const std::string csv = read_text(target);
    const auto lines = std::count(csv.begin(), csv.end(), '\n');
    CHECK(lines > 2);
    CHECK(contains(message, "after " + std::to_string(lines - 1) + " rows"));
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename());
    CHECK(names == std::vector<std::string>{"out.csv"});
  }
}

// ---------------------------------------------------------------------------------------------
// Item 4: every read is bounded, whatever the path names.

TEST_CASE("item 4: devices, FIFOs, standard input and directories are read with a bound",
          "[hostile-use]") {
  const fs::path dir = scratch_dir("reads");
  const auto analyze = [&](const std::string& file, const std::string& in = "/dev/null") {
    return run_bounded({"analyze", file, "--t0", "0", "--t1", "1", "--steps", "1"}, dir, in);
  };
  // /dev/zero: the old code reached 2 GB and bad_alloc (here: 1 GiB and exit 1).
  auto r = analyze("/dev/zero");
  CHECK(r.exit_code == 2);
  require_one_error_line(r);
  CHECK(contains(r.err, "/dev/zero: file: the mechanism file is larger than 1048576 bytes"));
  // `yes | kinegen analyze /dev/stdin`: a pipe that never ends.
  const fs::path fifo = dir / "yes.fifo";
  REQUIRE(::mkfifo(fifo.c_str(), 0644) == 0);
  std::thread yes([&] {
    ::signal(SIGPIPE, SIG_IGN);
    const int fd = ::open(fifo.c_str(), O_WRONLY);
    const std::string chunk(4096, 'y');
    while (fd >= 0 && ::write(fd, chunk.data(), chunk.size()) > 0) {
    }
    if (fd >= 0) ::close(fd);
  });
  r = analyze("/dev/stdin", fifo.string());
  yes.join();
  CHECK(r.exit_code == 2);
  CHECK(contains(r.err, "the mechanism file is larger than 1048576 bytes"));
  // A directory says so (it was "the file is empty").
  r = analyze(dir.string());
  CHECK(r.exit_code == 2);
  CHECK(contains(r.err, "is a directory"));
  // Tables and --input files must be regular files, and are read with their bound too.
  r = run_bounded({"analyze", source("tests/mechanisms/pieces_drive.yaml"), "--input",
                   "stroke=/dev/zero", "--t0", "0", "--t1", "1", "--steps", "1"},
                  dir);
  CHECK(r.exit_code == 2);
  CHECK(contains(r.err, "the table '/dev/zero' is not a regular file"));
  // A view --csv run from a pipe is held in memory up to its bound; a line is bounded anyway.
  r = run_bounded({"view", source("examples/four_bar.yaml"), "--csv", "/dev/zero", "-o",
                   (dir / "page.html").string()},
                  dir);
  CHECK(r.exit_code == 2);
  CHECK((contains(r.err, "'/dev/zero' is larger than 268435456 bytes") ||
         contains(r.err, "viewer")));  // a build without the viewer refuses before reading
  // The library's reader: a regular file within the bound is read whole.
  const kc::FileText text = kc::read_bounded(source("examples/four_bar.yaml"), 1 << 20);
  CHECK(text.ok());
  CHECK(text.text == read_text(source("examples/four_bar.yaml")));
  CHECK(kc::read_bounded(source("examples/four_bar.yaml"), 100).status ==
        kc::FileText::Status::kTooLarge);
}

// ---------------------------------------------------------------------------------------------
// Item 5: what keeps its rows in memory refuses a count beyond 2^24 numbers, before any work.

TEST_CASE("item 5: tolerance, animate and check refuse a count that would not fit",
          "[hostile-use]") {
  const fs::path dir = scratch_dir("counts");
  const std::string mech = source("examples/four_bar.yaml");
  const std::vector<std::vector<std::string>> commands = {
      {"tolerance", mech, "--tol", "a=0.01", "--t0", "0", "--t1", "1", "--steps", "2000000000"},
      {"animate", mech, "--t0", "0", "--t1", "1", "--steps", "2000000000", "-o",
       (dir / "a.svg").string()},
      {"check", mech, "--samples", "2000000000"}};
  for (const auto& args : commands) {
    const auto r = run_bounded(args, dir);
    INFO(args[0] << ": " << r.err);
    CHECK(r.exit_code == 2);
    require_one_error_line(r);
    CHECK(contains(r.err, args[0] + " keeps its rows in memory, at most 16777216 numbers"));
    CHECK(contains(r.err, "is the most that fits here"));
  }
  // The largest --steps it names does fit (tolerance: 15 numbers per row for the four-bar).
  CHECK_NOTHROW(kc::require_kept_rows("tolerance", 1118480 + 1, 15));
  CHECK_THROWS_AS(kc::require_kept_rows("tolerance", 1118481 + 1, 15), kc::UsageError);
}

// ---------------------------------------------------------------------------------------------
// Item 6: tolerance's sums do not overflow. The four-bar's coupler point P moves linearly in
// px and py: dP.x/d(px, py) = (cos phi, -sin phi) of the coupler, so with both tolerances d its
// rss is exactly d at every row (independent of the analysis' numbers) and its worst case
// d (|cos| + |sin|).

TEST_CASE("item 6: rss and the Monte Carlo spread stay finite near 1e160", "[hostile-use]") {
  const auto m = kc::CompiledModel::from_file(source("examples/four_bar.yaml"));
  for (const double d : {1e-3, 1e160, 1e300}) {
    kc::ToleranceOptions o;
    o.tolerances = {{"px", d}, {"py", d}};
    o.grid = {0, 6.283185307179586, 12};
    o.monte_carlo = 4;
    const kc::ToleranceResult r = kc::tolerance_analysis(*m, o);
    const auto at = std::find(r.quantities.begin(), r.quantities.end(), "P.x");
    REQUIRE(at != r.quantities.end());
    const std::size_t q = at - r.quantities.begin();
    for (std::size_t row = 0; row < r.t.size(); ++row) {
      INFO("d = " << d << ", t = " << r.t[row]);
      CHECK(std::abs(r.rss[row][q] / d - 1) < 1e-14);
      for (std::size_t k = 0; k < r.quantities.size(); ++k) {
        CHECK(r.rss[row][k] <= r.worst[row][k]);
        CHECK(std::isfinite(r.mc_spread[row][k]));
        CHECK(std::isfinite(r.mc_std[row][k]));
        // n samples' standard deviation is at most spread sqrt(n / (n - 1)).
        CHECK(r.mc_std[row][k] <= r.mc_spread[row][k] * std::sqrt(4.0 / 3.0) * (1 + 1e-12));
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Item 7: the jump test at the local scale (docs/format.md: Pieces and `period`).

TEST_CASE("item 7: a jump next to a fast-growing piece is refused", "[hostile-use]") {
  const fs::path dir = scratch_dir("jump");
  try {
    model_of(dir, slider("f: [{until: 1, f: \"t\"}, {f: \"t + 0.01 + 1e8*(t-1)^6\"}]"));
    FAIL("the jump of 0.01 at t = 1 was accepted");
  } catch (const kc::InputError& e) {
    CHECK(contains(e.what(), "f jumps at the boundary t = 1: 1 before it, 1.01 after it"));
  }
  // The same growth without the jump is smooth: no error and no warning.
  const auto smooth = model_of(dir, slider("f: [{until: 1, f: \"t\"}, {f: \"t + 1e8*(t-1)^6\"}]"));
  CHECK(smooth->symbolic().warnings.empty());
  // A jump below 1e-9 of the local scale is none; the driven length's unit is the floor: a
  // 1e-11 jump of a law near 0 counts on a 1e-3 mechanism, not on a 1 m one.
  CHECK_NOTHROW(model_of(dir, slider("f: [{until: 1, f: \"0\"}, {f: \"1e-11\"}]")));
  const std::string small =
      "name: small\nbodies:\n  - {name: s, q0: [0, 0, 0]}\njoints:\n"
      "  - {type: translational, i: ground, j: s, si: [0, 0.001], sj: [0, 0.001], vi: [1, 0]}\n"
      "drivers:\n  - {type: absolute_x, body: s, f: [{until: 1, f: \"0\"}, {f: \"1e-11\"}]}\n";
  CHECK_THROWS_AS(model_of(dir, small), kc::InputError);
}

// ---------------------------------------------------------------------------------------------
// Item 8: each message names its cause and none contradicts its verdict.

TEST_CASE("item 8: a load that is not finite is named, not called singular", "[hostile-use]") {
  const fs::path dir = scratch_dir("loads");
  const std::string two_links =
      "name: two\nparameters: {m: 1}\nbodies:\n"
      "  - {name: a, q0: [0, 0, 0], mass: m, com: [0.5, 0]}\n"
      "  - {name: b, q0: [1, 0, 0], mass: m, com: [0.5, 0]}\n"
      "gravity: [0, -9.81]\njoints:\n  - {type: revolute, i: ground, j: a}\n"
      "  - {type: revolute, i: a, j: b, si: [1, 0]}\ndrivers:\n"
      "  - {type: absolute_angle, body: a, f: t}\n"
      "  - {type: relative_angle, i: a, j: b, f: \"0.3\"}\n";
  const auto force_failure = [&](const std::string& yaml, const std::vector<kc::ParamOverride>& p) {
    const auto m = model_of(dir, yaml, p);
    const kc::ForceModel forces = kc::forces_for_analysis(*m);
    kc::AnalysisOptions o;
    o.forces = &forces;
    try {
      kc::run_analysis(
          *m, {0, 1, 2}, [](const kc::StateRow&) {}, o);
    } catch (const kc::AnalysisError& e) {
      return std::string(e.what());
    }
    return std::string("no failure");
  };
  std::string e = force_failure(
      two_links + "forces:\n  - {type: torque, name: bad, body: b, value: \"log(phi_b - 1)\"}\n",
      {});
  INFO(e);
  CHECK(contains(e, "the load forces[0] 'bad' (torque) (line 14) is not finite here"));
  CHECK_FALSE(contains(e, "singular"));
  e = force_failure(two_links, {{"m", "1e308"}});
  INFO(e);
  CHECK(contains(e, "the weight of body 'a' (mass 1e+308"));
  CHECK_FALSE(contains(e, "singular"));
}

TEST_CASE("item 8: a table beyond a double and a driver's NaN are named", "[hostile-use]") {
  const fs::path dir = scratch_dir("tables");
  write_text(dir / "big.csv", "t,value\n0,0\n1,1\n2,1e308\n3,3\n4,4\n");
  try {
    model_of(dir, slider("table: big.csv"));
    FAIL("a spline beyond a double was accepted");
  } catch (const kc::InputError& e) {
    CHECK(contains(e.what(), "table 'big.csv': its spline's"));
    CHECK(contains(e.what(), "beyond a double"));
  }
  // A law that becomes NaN at t = 1: the row and its driver are named, and the first solve's
  // hint about q0 (which is not the cause) is not given.
  const auto m = model_of(dir, slider("f: \"sqrt(1 - t)\""));
  try {
    kc::run_analysis(*m, {0, 2, 4}, [](const kc::StateRow&) {});
    FAIL("no failure");
  } catch (const kc::AnalysisError& e) {
    CHECK(contains(e.what(),
                   "not finite at t = 1: nu (the velocity's right-hand side) of "
                   "drivers[0] 'lift' (absolute_x)"));
    CHECK_FALSE(contains(e.what(), "q0"));
  }
}

TEST_CASE("item 8: seeds out of range are refused, not wrapped", "[hostile-use]") {
  const std::string mech = source("examples/four_bar.yaml");
  for (const std::string seed : {"-1", "99999999999999999999999", "18446744073709551616", "1.5"}) {
    const auto r = run_kinegen({"tolerance", mech, "--tol", "a=0.01", "--t0", "0", "--t1", "1",
                                "--steps", "2", "--monte-carlo", "2", "--seed", seed});
    INFO(seed << ": " << r.err);
    CHECK(r.exit_code == 2);
    CHECK(contains(r.err, "--seed must be a whole number from 0 to 18446744073709551615"));
  }
  auto r = run_kinegen({"tolerance", mech, "--tol", "a=0.01", "--t0", "0", "--t1", "1", "--steps",
                        "2", "--monte-carlo", "2", "--seed", "18446744073709551615"});
  CHECK(r.exit_code == 0);
  CHECK(contains(r.out, "seed 18446744073709551615"));
  r = run_kinegen({"check", mech, "--samples", "1", "--seed", "4294967296"});
  CHECK(r.exit_code == 2);
  CHECK(contains(r.err, "--seed must be a whole number from 0 to 4294967295"));
}

TEST_CASE("item 8: a rack's direction of 1e-300 is a direction", "[hostile-use]") {
  const fs::path dir = scratch_dir("rack");
  const std::string steering = read_text(source("examples/gears/steering.yaml"));
  const std::string from = "vi: [1, 0]";
  const auto at = steering.find(from);
  REQUIRE(at != std::string::npos);
  std::string tiny = steering;
  tiny.replace(at, from.size(), "vi: [1e-300, 0]");
  fs::copy_file(source("examples/gears/steering.yaml"), dir / "unit.yaml");
  const auto unit = kc::CompiledModel::from_file((dir / "unit.yaml").string());
  const auto scaled = model_of(dir, tiny);  // refused as "the zero vector" before
  std::vector<kc::StateRow> a, b;
  kc::run_analysis(*unit, {0, 1, 8}, [&](const kc::StateRow& r) { a.push_back(r); });
  kc::run_analysis(*scaled, {0, 1, 8}, [&](const kc::StateRow& r) { b.push_back(r); });
  REQUIRE(a.size() == b.size());
  for (std::size_t k = 0; k < a.size(); ++k) CHECK((a[k].q - b[k].q).cwiseAbs().maxCoeff() < 1e-12);
}
