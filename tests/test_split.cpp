// Split functions (kinegen generate --max-function-ops, docs/scale.md): the test mechanisms
// generated with a threshold of 8 operations, so that the functions and the block solvers
// come in several parts, compute what the unsplit headers compute. The parts evaluate the same
// expression trees in the same order, so the results agree to rounding at most.
#include <algorithm>
#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "all_types.hpp"
#include "all_types_split.hpp"
#include "closed_chain_4.hpp"
#include "closed_chain_4_split.hpp"
#ifdef KINEGEN_TORN_SPLIT
#include "closed_chain_10.hpp"
#include "closed_chain_10_torn.hpp"
#endif
#include "fourbar_chain_3.hpp"
#include "fourbar_chain_3_rolled.hpp"
#include "fourbar_chain_3_rolled_split.hpp"
#include "fourbar_chain_3_split.hpp"
#include "guarded_slider.hpp"
#include "guarded_slider_split.hpp"
#include "scissor_lift_3.hpp"
#include "scissor_lift_3_rolled.hpp"
#include "scissor_lift_3_rolled_split.hpp"
#include "scissor_lift_3_split.hpp"
#include "support/run_command.hpp"

namespace {

using namespace kinegen::models;

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

template <std::size_t N>
void check_close(const std::array<double, N>& a, const std::array<double, N>& b, int n,
                 const char* what) {
  INFO(what);
  for (int k = 0; k < n; ++k) {
    INFO("index " << k << ": " << a[k] << " vs " << b[k]);
    CHECK(std::isfinite(a[k]));
    CHECK(std::abs(a[k] - b[k]) <= 1e-14 * std::max(1.0, std::abs(a[k])));
  }
}

template <class RW, class RS>
void check_reports(const RW& a, const RS& b) {
  CHECK(a.status == b.status);
  CHECK(a.block == b.block);
  CHECK(a.iterations == b.iterations);
  CHECK(a.total_iterations == b.total_iterations);
}

// Split: the header <name>_<variant>.hpp, which must contain each of `markers` (it really is
// split, or rolled: the comparison would pass trivially otherwise).
template <class Whole, class Split>
void compare(const std::string& name, const std::string& variant = "split",
             const std::vector<std::string>& markers = {"_part1("}) {
  static_assert(Whole::nq == Split::nq && Whole::nc == Split::nc &&
                Whole::jac_nnz == Split::jac_nnz);
  constexpr int nq = Whole::nq, nc = Whole::nc, n_out = nc + Whole::jac_nnz + 1;
  INFO(name << "_" << variant);
  const std::string text =
      read_text(std::string(KINEGEN_SPLIT_DIR) + "/" + name + "_" + variant + ".hpp");
  for (const std::string& marker : markers) CHECK(text.find(marker) != std::string::npos);

  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  const typename Whole::Params pw{};
  const typename Split::Params ps{};
  for (int sample = 0; sample < 6; ++sample) {
    const double t = 0.37 * sample;
    std::array<double, nq> q{}, qd{};
    for (int k = 0; k < nq; ++k) {
      q[k] = Whole::q0[k] + (sample == 0 ? 0 : 0.2 * u(rng));
      qd[k] = u(rng);
    }
    std::array<double, n_out> a{}, b{};
    Whole::phi(q.data(), t, pw, a.data());
    Split::phi(q.data(), t, ps, b.data());
    check_close(a, b, nc, "phi");
    Whole::phi_q(q.data(), t, pw, a.data());
    Split::phi_q(q.data(), t, ps, b.data());
    check_close(a, b, Whole::jac_nnz, "phi_q");
    Whole::nu(q.data(), t, pw, a.data());
    Split::nu(q.data(), t, ps, b.data());
    check_close(a, b, nc, "nu");
    Whole::gamma(q.data(), qd.data(), t, pw, a.data());
    Split::gamma(q.data(), qd.data(), t, ps, b.data());
    check_close(a, b, nc, "gamma");

    if constexpr (Whole::has_block_solver) {
      // From a start near the assembled configuration: solve, then the motion solves.
      std::array<double, nq> qa{}, qb{};
      for (int k = 0; k < nq; ++k) qa[k] = qb[k] = Whole::q0[k] + 1e-3 * u(rng);
      const typename Whole::BlockOptions ow{};
      const typename Split::BlockOptions os{};
      const double ts = 0.05 * sample;
      const auto rw = Whole::solve_position(qa.data(), ts, pw, ow);
      const auto rs = Split::solve_position(qb.data(), ts, ps, os);
      check_reports(rw, rs);
      REQUIRE(rw.status == 0);  // a converged solve, so that the motion solves mean something
      check_close(qa, qb, nq, "solve_position q");
      std::array<double, nq> va{}, vb{}, aa{}, ab{};
      check_reports(Whole::solve_velocity(qa.data(), ts, pw, va.data(), ow),
                    Split::solve_velocity(qa.data(), ts, ps, vb.data(), os));
      check_close(va, vb, nq, "solve_velocity qd");
      check_reports(Whole::solve_acceleration(qa.data(), va.data(), ts, pw, aa.data(), ow),
                    Split::solve_acceleration(qa.data(), va.data(), ts, ps, ab.data(), os));
      check_close(aa, ab, nq, "solve_acceleration qdd");
      va.fill(0), vb.fill(0), aa.fill(0), ab.fill(0);
      check_reports(
          Whole::solve_velocity_acceleration(qa.data(), ts, pw, va.data(), aa.data(), ow),
          Split::solve_velocity_acceleration(qa.data(), ts, ps, vb.data(), ab.data(), os));
      check_close(va, vb, nq, "solve_velocity_acceleration qd");
      check_close(aa, ab, nq, "solve_velocity_acceleration qdd");
      // Full steps from the solved configuration.
      for (int step = 1; step <= 3; ++step) {
        const double ti = ts + 0.01 * step;
        check_reports(Whole::solve_step(qa.data(), ti, pw, va.data(), aa.data(), ow),
                      Split::solve_step(qb.data(), ti, ps, vb.data(), ab.data(), os));
        check_close(qa, qb, nq, "solve_step q");
        check_close(va, vb, nq, "solve_step qd");
        check_close(aa, ab, nq, "solve_step qdd");
      }
      // And with the sin/cos cache (the split and rolled rates read it too), over steps
      // small enough for rotations and one large enough to move the anchors.
      std::array<double, Split::trig_cache_size> trig{};
      trig.fill(std::nan(""));
      for (int step = 1; step <= 4; ++step) {
        const double ti = ts + 0.03 + (step == 3 ? 0.5 : 0.01 * step);
        check_reports(Whole::solve_step(qa.data(), ti, pw, va.data(), aa.data(), ow),
                      Split::solve_step(qb.data(), ti, ps, vb.data(), ab.data(), os, trig.data()));
        check_close(qa, qb, nq, "solve_step q, trig cache");
        check_close(va, vb, nq, "solve_step qd, trig cache");
        check_close(aa, ab, nq, "solve_step qdd, trig cache");
      }
    }
  }
}

}  // namespace

TEST_CASE("split functions compute what the whole functions compute", "[split]") {
  // The chains have several blocks, so their block solvers are split too.
  for (const char* name : {"fourbar_chain_3", "scissor_lift_3"}) {
    const std::string text = read_text(std::string(KINEGEN_SPLIT_DIR) + "/" + name + "_split.hpp");
    CHECK(text.find("static void _gamma_part1(") != std::string::npos);
    CHECK(text.find("static BlockReport<_real<T>> _solve_position_part1(") != std::string::npos);
    CHECK(text.find("static BlockReport<_real<T>> _solve_velocity_acceleration_part1(") != std::string::npos);
  }
  compare<fourbar_chain_3, fourbar_chain_3_split>("fourbar_chain_3");
  compare<scissor_lift_3, scissor_lift_3_split>("scissor_lift_3");
  compare<closed_chain_4, closed_chain_4_split>("closed_chain_4");
  compare<all_types, all_types_split>("all_types");
  compare<guarded_slider, guarded_slider_split>("guarded_slider");
}

TEST_CASE("repeated blocks emitted once compute what the whole block solver computes",
          "[split][roll]") {
  // --roll-min 2: the chains' alike Newton blocks (the 2 x 2 loops of the four-bar chain, the
  // torn 6 x 6 stages of the scissor lift) are one function each, called with coordinate
  // tables; alone and in split headers.
  compare<fourbar_chain_3, fourbar_chain_3_rolled>("fourbar_chain_3", "rolled",
                                                   {"_roll0_position(", "_roll0_i[3]["});
  compare<fourbar_chain_3, fourbar_chain_3_rolled_split>("fourbar_chain_3", "rolled_split",
                                                         {"_roll0_position(", "_part1("});
  compare<scissor_lift_3, scissor_lift_3_rolled>("scissor_lift_3", "rolled", {"_roll0_position("});
  compare<scissor_lift_3, scissor_lift_3_rolled_split>("scissor_lift_3", "rolled_split",
                                                       {"_roll0_position(", "_part1("});
}

TEST_CASE("a part stores at most max_function_ops / 5 outputs", "[split]") {
  // g++ -O2 compares each store with the earlier stores of its function, so parts are cut by
  // their number of outputs too (docs/scale.md). fourbar_chain_3's phi_q has 32 operations but
  // 51 outputs: with a threshold of 50 it is split by outputs alone, into parts of 10.
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(KINEGEN_TEST_TMP) / "split_outputs";
  fs::create_directories(dir);
  const auto r = kinegen::test::run_command(
      {KINEGEN_EXE, "generate",
       std::string(KINEGEN_SOURCE_DIR) + "/tests/mechanisms/fourbar_chain_3.yaml", "-o",
       dir.string(), "--quiet", "--max-function-ops", "50"});
  REQUIRE(r.exit_code == 0);
  const std::string text = read_text((dir / "fourbar_chain_3.hpp").string());
  // Every function's parts: "// out[first..last]; K operations", then the public function's
  // "// out[size]; K operations in P parts".
  const std::regex part(R"(// out\[(\d+)\.\.(\d+)\]; (\d+) operations\n)");
  std::vector<std::pair<int, int>> ranges;
  int functions = 0;
  const auto begin = std::sregex_iterator(text.begin(), text.end(), part);
  for (auto it = begin; it != std::sregex_iterator(); ++it) {
    const int first = std::stoi((*it)[1]), last = std::stoi((*it)[2]);
    const int ops = std::stoi((*it)[3]);
    INFO("part out[" << first << ".." << last << "]");
    CHECK(last - first + 1 <= 10);
    CHECK(ops <= 50 + 20);  // one output's terms are never split; none has 20 here
    if (first == 0)
      ++functions;
    else
      CHECK(first == ranges.back().second + 1);  // contiguous
    ranges.push_back({first, last});
  }
  CHECK(functions == 4);  // phi, phi_q, nu and gamma are all split
  std::smatch m;
  REQUIRE(std::regex_search(text, m,
                            std::regex(R"(// out\[jac_nnz\]; (\d+) operations in (\d+) parts)")));
  CHECK(std::stoi(m[1]) <= 50);  // split for its outputs, not its operations
  CHECK(std::stoi(m[2]) == 6);   // 51 outputs in parts of at most 10
}

namespace {

template <std::size_t N>
bool same_bits(const std::array<double, N>& a, const std::array<double, N>& b) {
  return std::memcmp(a.data(), b.data(), sizeof(double) * N) == 0;
}

// The parts of torn block `block` in a header: the number of its position parts.
int torn_position_parts(const std::string& text, int block) {
  const std::regex part("static void _torn" + std::to_string(block) + R"(_position_part\d+\()");
  return static_cast<int>(
      std::distance(std::sregex_iterator(text.begin(), text.end(), part), std::sregex_iterator()));
}

// A torn block split into parts computes the same doubles as the whole block: the parts
// evaluate the same expression trees on the same values (sin and cos of the block's coordinates
// pass between them in _sc), so over a full turn of the crank every solve agrees bit for bit.
template <class Whole, class Split>
void compare_bits(const std::string& name, int min_parts) {
  static_assert(Whole::nq == Split::nq && Whole::num_blocks == Split::num_blocks);
  constexpr int nq = Whole::nq;
  INFO(name);
  const std::string split_text = read_text(std::string(KINEGEN_SPLIT_DIR) + "/" + name + ".hpp");
  int torn = -1;
  for (int b = 0; b < Split::num_blocks && torn < 0; ++b)
    if (torn_position_parts(split_text, b) > 0) torn = b;
  REQUIRE(torn >= 0);
  CHECK(torn_position_parts(split_text, torn) >= min_parts);
  CHECK(split_text.find("_torn" + std::to_string(torn) + "_sensitivities_part1(") !=
        std::string::npos);
  CHECK(split_text.find("_torn" + std::to_string(torn) + "_qdd_part1(") != std::string::npos);

  const typename Whole::Params pw{};
  const typename Split::Params ps{};
  const typename Whole::BlockOptions ow{};
  const typename Split::BlockOptions os{};
  for (const bool cache : {false, true}) {
    INFO("trig cache " << cache);
    std::array<double, nq> qa{}, qb{}, va{}, vb{}, aa{}, ab{};
    for (int k = 0; k < nq; ++k) qa[k] = qb[k] = Whole::q0[k];
    std::array<double, Whole::trig_cache_size> ta{};
    std::array<double, Split::trig_cache_size> tb{};
    ta.fill(std::nan(""));
    tb.fill(std::nan(""));
    signed char sa[Whole::num_blocks] = {}, sb[Split::num_blocks] = {};
    for (int step = 0; step <= 126; ++step) {  // t from 0 to 6.3 > 2 pi: a full turn
      const double t = 0.05 * step;
      INFO("t = " << t);
      const auto rw = Whole::solve_step(qa.data(), t, pw, va.data(), aa.data(), ow,
                                        cache ? ta.data() : nullptr, sa);
      const auto rs = Split::solve_step(qb.data(), t, ps, vb.data(), ab.data(), os,
                                        cache ? tb.data() : nullptr, sb);
      check_reports(rw, rs);
      REQUIRE(rw.status == 0);
      CHECK(rw.residual == rs.residual);
      CHECK(rw.rcond == rs.rcond);
      REQUIRE(same_bits(qa, qb));
      REQUIRE(same_bits(va, vb));
      REQUIRE(same_bits(aa, ab));
      // The public functions alone, from the step's solution (a start one step behind).
      std::array<double, nq> pa = qa, pb = qb, xa{}, xb{}, ya{}, yb{};
      for (int k = 0; k < nq; ++k) pa[k] = pb[k] = qa[k] - 0.05 * va[k];
      check_reports(Whole::solve_position(pa.data(), t, pw, ow),
                    Split::solve_position(pb.data(), t, ps, os));
      REQUIRE(same_bits(pa, pb));
      check_reports(Whole::solve_velocity_acceleration(qa.data(), t, pw, xa.data(), ya.data(), ow),
                    Split::solve_velocity_acceleration(qa.data(), t, ps, xb.data(), yb.data(), os));
      REQUIRE(same_bits(xa, xb));
      REQUIRE(same_bits(ya, yb));
      check_reports(Whole::solve_velocity(qa.data(), t, pw, xa.data(), ow),
                    Split::solve_velocity(qa.data(), t, ps, xb.data(), os));
      REQUIRE(same_bits(xa, xb));
      check_reports(Whole::solve_acceleration(qa.data(), xa.data(), t, pw, ya.data(), ow),
                    Split::solve_acceleration(qa.data(), xa.data(), t, ps, yb.data(), os));
      REQUIRE(same_bits(ya, yb));
    }
  }
}

}  // namespace

TEST_CASE("a torn block in parts computes the whole block's doubles", "[split][torn]") {
  // closed_chain_4_split (--max-function-ops 8): one assigned coordinate per part.
  compare_bits<closed_chain_4, closed_chain_4_split>("closed_chain_4_split", 3);
#ifdef KINEGEN_TORN_SPLIT
  compare_bits<closed_chain_10, closed_chain_10_torn>("closed_chain_10_torn", 3);
#endif
}
