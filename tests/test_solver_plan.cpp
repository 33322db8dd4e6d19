// The structure stage's SolverPlan (structure/solver_plan.hpp): the classes of repeated blocks
// and the cuts of a split solver are decided there, as data, before anything is printed. The
// chains of tests/mechanisms are built loop by loop from one pattern (their comments say how),
// so which blocks are alike is known without the code.
#include <catch2/catch.hpp>
#include <set>
#include <string>

#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/structure/solver_plan.hpp"

namespace cg = kinegen::codegen;

namespace {

struct Planned {
  std::unique_ptr<cg::CompiledModel> model;
  cg::Structure st;
};

Planned load(const std::string& name) {
  Planned p;
  p.model = cg::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) + "/tests/mechanisms/" +
                                         name + ".yaml");
  p.st = cg::analyze_structure(p.model->symbolic(), p.model->symbols());
  return p;
}

cg::SolverPlan plan(const Planned& p, int max_ops, int roll_min) {
  return cg::plan_block_solver(p.model->symbolic(), p.model->symbols(), p.st, max_ops, roll_min);
}

// Every member's table starts with its block's own coordinates; the tables of a class have one
// length; class_of / member_of point back at the members.
void check_classes(const cg::SolverPlan& sp) {
  const int nb = static_cast<int>(sp.structure.plans.size());
  REQUIRE(static_cast<int>(sp.class_of.size()) == nb);
  int previous_first = -1;
  for (std::size_t g = 0; g < sp.repeated.size(); ++g) {
    const cg::RepeatedBlocks& r = sp.repeated[g];
    CHECK(r.blocks.front() > previous_first);  // classes in the order of their first blocks
    previous_first = r.blocks.front();
    REQUIRE(r.alone);
    CHECK(r.alone->structure.plans.size() == 1);
    CHECK(r.alone->repeated.empty());
    CHECK(r.alone->ranges.empty());
    for (std::size_t m = 0; m < r.blocks.size(); ++m) {
      const int b = r.blocks[m];
      CHECK(sp.class_of[b] == static_cast<int>(g));
      CHECK(sp.member_of[b] == static_cast<int>(m));
      if (m > 0) CHECK(b > r.blocks[m - 1]);
      const auto& cols = sp.structure.plans[b].block.cols;
      REQUIRE(r.coords[m].size() == r.coords[0].size());
      CHECK(std::vector<int>(r.coords[m].begin(), r.coords[m].begin() + cols.size()) == cols);
      CHECK(r.slots[m].size() == r.slots[0].size());
    }
  }
}

}  // namespace

TEST_CASE("solver plan: a chain's alike loops form one class", "[structure][plan]") {
  SECTION("four-bar chain: 3 loops") {
    const Planned p = load("fourbar_chain_3");
    const cg::SolverPlan sp = plan(p, 0, 2);
    check_classes(sp);
    REQUIRE(sp.repeated.size() == 1);
    CHECK(sp.repeated[0].blocks.size() == 3);
    // The members solve different coordinates.
    std::set<int> own;
    for (int b : sp.repeated[0].blocks)
      for (int c : sp.structure.plans[b].block.cols) CHECK(own.insert(c).second);
    // Fewer alike blocks than roll_min: no class.
    const cg::SolverPlan none = plan(p, 0, 4);
    CHECK(none.repeated.empty());
    for (int c : none.class_of) CHECK(c == -1);
    // Not rolling at all leaves the program as it is.
    CHECK(plan(p, 0, 0).program.program.nodes.size() == sp.program.program.nodes.size());
  }
  SECTION("scissor lift: its torn stages") {
    const Planned p = load("scissor_lift_3");
    const cg::SolverPlan sp = plan(p, 0, 2);
    check_classes(sp);
    REQUIRE(!sp.repeated.empty());
    for (const auto& r : sp.repeated) CHECK(r.alone->structure.plans[0].torn());
  }
}

TEST_CASE("solver plan: parts cover the blocks and a torn block's assignments in order",
          "[structure][plan]") {
  const Planned p = load("closed_chain_4");
  CHECK(plan(p, 0, 0).ranges.empty());
  const cg::SolverPlan sp = plan(p, 8, 0);
  const int nb = static_cast<int>(sp.structure.plans.size());
  REQUIRE(sp.ranges.size() > 1);
  int next = 0;
  for (const auto& [first, last] : sp.ranges) {
    CHECK(first == next);
    CHECK(last > first);
    next = last;
  }
  CHECK(next == nb);
  REQUIRE(sp.torn_any);
  int rotated = 0;
  for (int b = 0; b < nb; ++b) {
    if (!sp.torn_split(b)) continue;
    const cg::TornParts& tp = sp.torn_parts[b];
    const int assigned = static_cast<int>(sp.structure.plans[b].assigned.size());
    for (const cg::PartRanges* ranges : {&tp.position, &tp.rates}) {
      int a = 0;
      for (const auto& [first, last] : *ranges) {
        CHECK(first == a);
        a = last;
      }
      CHECK(a == assigned);
    }
    CHECK(tp.trig_first == rotated);
    for (std::size_t i = 0; i < tp.rotated.size(); ++i)
      CHECK(sp.torn_trig[tp.trig_first + i][0] == tp.rotated[i]);
    rotated += static_cast<int>(tp.rotated.size());
  }
  CHECK(rotated == static_cast<int>(sp.torn_trig.size()));
}
