#include "kinegen/codegen/structure/solver_plan.hpp"

#include <algorithm>
#include <limits>
#include <set>
#include <sstream>
#include <string>

#include "kinegen/codegen/program/repeated.hpp"

namespace kinegen::codegen {

std::vector<std::pair<std::pair<int, int>, int>> row_entries(
    const std::map<std::pair<int, int>, int>& entries, int r) {
  std::vector<std::pair<std::pair<int, int>, int>> row;
  for (auto it = entries.lower_bound({r, std::numeric_limits<int>::min()});
       it != entries.end() && it->first.first == r; ++it)
    row.push_back(*it);
  return row;
}

std::vector<int> SolverPlan::block_outputs(std::size_t b) const {
  std::vector<int> ids;
  for (int o = program.position_first[b]; o < program.position_last(b); ++o) ids.push_back(o);
  const BlockRates& bo = program.rates[b];
  ids.insert(ids.end(), bo.jbb.begin(), bo.jbb.end());
  for (const auto& [rc, o] : bo.tjac) ids.push_back(o);
  for (const auto& row : bo.coupling)
    for (const auto& [c, o] : row) ids.push_back(o);
  ids.insert(ids.end(), bo.nu.begin(), bo.nu.end());
  ids.insert(ids.end(), bo.gamma.begin(), bo.gamma.end());
  return ids;
}

std::vector<int> SolverPlan::torn_host_outputs(std::size_t b, bool position, bool rates) const {
  const BlockPlan& plan = structure.plans[b];
  const BlockRates& bo = program.rates[b];
  const auto& rows = plan.block.rows;
  std::vector<int> ids;
  const int f = program.position_first[b] + static_cast<int>(plan.assigned.size());
  for (std::size_t i = 0; i < plan.residuals.size(); ++i) {
    const int r = plan.residuals[i];
    const std::size_t ri = std::lower_bound(rows.begin(), rows.end(), r) - rows.begin();
    if (position) {
      ids.push_back(program.output(f + static_cast<int>(i)));
      for (const auto& [rc, o] : row_entries(program.torn_jacobian[b], r))
        ids.push_back(program.output(o));
    }
    if (rates) {
      for (const auto& [rc, o] : row_entries(bo.tjac, r)) ids.push_back(program.output(o));
      ids.push_back(program.output(bo.nu[ri]));
      ids.push_back(program.output(bo.gamma[ri]));
    }
    for (const auto& [c, o] : bo.coupling[ri]) ids.push_back(program.output(o));
  }
  return ids;
}

namespace {

// Block bi's structure with its coordinate table's slots for the coordinates (its size
// `list_size`): its rows, tears, residuals, assignments, torn Jacobian entries and
// couplings, the part of a repeated block's key before its expressions.
std::string shape_key(const SolverPlan& sp, int bi, std::size_t list_size,
                      const std::map<int, int>& slot) {
  const BlockPlan& plan = sp.structure.plans[bi];
  const BlockProgram& bp = sp.program;
  const Block& b = plan.block;
  const auto row_of = [&](int r) {
    return std::lower_bound(b.rows.begin(), b.rows.end(), r) - b.rows.begin();
  };
  std::ostringstream key;
  key << b.rows.size() << " " << list_size << " t";
  for (int c : plan.tears) key << " " << slot.at(c);
  key << " r";
  for (int r : plan.residuals) key << " " << row_of(r);
  key << " a";
  for (const auto& [r, c] : plan.assigned) key << " " << row_of(r) << ":" << slot.at(c);
  key << " j";
  for (const auto& [rc, o] : bp.torn_jacobian[bi])
    key << " " << row_of(rc.first) << ":" << slot.at(rc.second);
  key << " c";
  for (const auto& row : bp.rates[bi].coupling) {
    for (const auto& [c, o] : row) key << " " << slot.at(c);
    key << " |";
  }
  return key.str();
}

// The structure of a model with block `first` of st alone (for a repeated block's functions).
Structure single_block(const Structure& st, int first) {
  const int nq = static_cast<int>(st.order.col_block.size());
  Structure sub;
  sub.order.perfect = true;
  sub.order.blocks = {st.plans[first].block};
  sub.order.col_block.assign(nq, -1);
  sub.order.row_block.assign(st.order.row_block.size(), -1);
  for (int c : st.plans[first].block.cols) sub.order.col_block[c] = 0;
  for (int row : st.plans[first].block.rows) sub.order.row_block[row] = 0;
  sub.plans = {st.plans[first]};
  return sub;
}

// The classes of repeated Newton blocks (RepeatedBlocks) of at least roll_min members.
void find_repeated_blocks(SolverPlan& sp, const SymbolicModel& model, const SymbolTable& symbols,
                          int roll_min) {
  const Structure& st = sp.structure;
  const BlockProgram& bp = sp.program;
  const int nb = static_cast<int>(st.plans.size());
  const int nq = static_cast<int>(st.order.col_block.size());
  std::map<std::string, std::vector<int>> groups;
  std::vector<std::vector<int>> coords(nb);
  std::vector<std::vector<GiNaC::ex>> renamed(nb);
  for (int bi = 0; bi < nb; ++bi) {
    const BlockPlan& plan = st.plans[bi];
    if (plan.kind != BlockKind::kNewton) continue;
    const Block& b = plan.block;
    const std::vector<int> ids = sp.block_outputs(bi);
    std::set<int> read;
    for (int id : ids) add_coordinates_read(bp.exprs[id], symbols, read);
    for (const auto& row : bp.rates[bi].coupling)
      for (const auto& [c, o] : row) read.insert(c);
    std::vector<int> list = b.cols;
    for (int c : read)
      if (!std::binary_search(b.cols.begin(), b.cols.end(), c)) list.push_back(c);
    std::map<int, int> slot;
    for (std::size_t j = 0; j < list.size(); ++j) slot[list[j]] = static_cast<int>(j);
    const GiNaC::exmap rename = table_renaming(list, symbols);
    std::ostringstream key;
    key << shape_key(sp, bi, list.size(), slot);
    key << " e";
    for (int id : ids) {
      renamed[bi].push_back(bp.exprs[id].subs(rename));
      key << " " << renamed[bi].back() << ";";
    }
    coords[bi] = list;
    groups[key.str()].push_back(bi);
  }
  for (const std::vector<int>& members : by_first_member(std::move(groups))) {
    if (static_cast<int>(members.size()) < roll_min) continue;
    const int first = members[0];
    std::vector<int> alike;
    for (int bi : members)
      if (same_expressions(renamed[bi], renamed[first])) alike.push_back(bi);
    if (static_cast<int>(alike.size()) < roll_min) continue;
    const Structure sub = single_block(st, first);
    RepeatedBlocks r;
    r.alone = std::make_shared<const SolverPlan>(plan_block_solver(model, symbols, sub, 0, 0));
    const BlockProgram& alone = r.alone->program;
    std::vector<int> local(nq, -1);
    for (std::size_t j = 0; j < coords[first].size(); ++j)
      local[coords[first][j]] = static_cast<int>(j);
    // The trig cache slots of each block's coordinates, in the order of alone's slots.
    std::vector<int> by_slot(alone.trig_slots, -1);
    for (int c = 0; c < nq; ++c)
      if (alone.trig_slot[c] >= 0) by_slot[alone.trig_slot[c]] = local[c];
    for (int bi : alike) {
      std::vector<int> slots;
      bool ok = true;
      for (int j : by_slot) {
        const int s = j < 0 ? -1 : bp.trig_slot[coords[bi][j]];
        ok = ok && s >= 0;
        slots.push_back(s);
      }
      if (!ok) continue;
      sp.class_of[bi] = static_cast<int>(sp.repeated.size());
      sp.member_of[bi] = static_cast<int>(r.blocks.size());
      r.blocks.push_back(bi);
      r.coords.push_back(coords[bi]);
      r.slots.push_back(slots);
    }
    if (r.blocks.empty()) continue;
    sp.repeated.push_back(std::move(r));
  }
}

// The parts of a split solver, cut once by partition(): runs of consecutive blocks (ranges),
// and within a torn block whose assignments alone exceed the budget, runs of its assigned
// coordinates (torn_parts). Later blocks read earlier blocks' coordinates from q (qd, qdd), so
// a run needs nothing from the runs before it but memory; its terms are its own.
void split_blocks(SolverPlan& sp, int max_ops) {
  const Structure& st = sp.structure;
  const BlockProgram& bp = sp.program;
  const Program& prog = bp.program;
  const int n = static_cast<int>(st.plans.size());
  sp.torn_parts.assign(n, {});
  for (int bi = 0; bi < n; ++bi) {
    const BlockPlan& plan = st.plans[bi];
    if (!plan.torn() || sp.class_of[bi] >= 0) continue;
    TornParts& tp = sp.torn_parts[bi];
    const int f = bp.position_first[bi], m = static_cast<int>(plan.tears.size());
    const BlockRates& bo = bp.rates[bi];
    const auto& rows = plan.block.rows;
    // A position part assigns its coordinates (one store each) and, except in the last pass,
    // their m sensitivities; a rates part computes the sensitivities again, or the qd or qdd
    // of its coordinates (a store each and one more for the correction by the tears).
    tp.position = partition(prog, max_ops, static_cast<int>(plan.assigned.size()), [&](int a) {
      PartCost c{{bp.output(f + a)}, 0, 1 + m};
      for (const auto& [rc, o] : row_entries(bp.torn_jacobian[bi], plan.assigned[a].first))
        c.nodes.push_back(bp.output(o));
      return c;
    });
    tp.rates = partition(prog, max_ops, static_cast<int>(plan.assigned.size()), [&](int a) {
      const int r = plan.assigned[a].first;
      const std::size_t i = std::lower_bound(rows.begin(), rows.end(), r) - rows.begin();
      PartCost c{{bp.output(bo.nu[i]), bp.output(bo.gamma[i])}, 0, m + 4};
      for (const auto& [rc, o] : row_entries(bo.tjac, r)) c.nodes.push_back(bp.output(o));
      for (const auto& [col, o] : bo.coupling[i]) c.nodes.push_back(bp.output(o));
      return c;
    });
    if (tp.position.size() == 1 && tp.rates.size() == 1) {
      tp = TornParts{};
      continue;
    }
    tp.dependency = sp.tear_dependency(bi);
    tp.trig_first = static_cast<int>(sp.torn_trig.size());
    for (int c : plan.block.cols)
      if (bp.trig_slot[c] >= 0) {
        tp.rotated.push_back(c);
        sp.torn_trig.push_back({c, bp.trig_slot[c]});
      }
  }
  sp.torn_any = std::any_of(sp.torn_parts.begin(), sp.torn_parts.end(),
                            [](const TornParts& tp) { return !tp.position.empty(); });
  if (prog.operation_count() <= max_ops && !sp.torn_any) return;
  sp.ranges = partition(prog, max_ops, n, [&](int bi) {
    if (sp.class_of[bi] >= 0) return PartCost{{}, 4, 1};  // a call: a few statements, one store
    // A split torn block: its Newton loop and its calls.
    const TornParts& tp = sp.torn_parts[bi];
    if (!tp.position.empty()) {
      const int calls = static_cast<int>(tp.position.size() + 5 * tp.rates.size());
      return PartCost{sp.torn_host_outputs(bi), 4 * calls,
                      calls + 3 * static_cast<int>(st.plans[bi].tears.size())};
    }
    PartCost c;
    for (int o : sp.block_outputs(bi)) c.nodes.push_back(bp.output(o));
    // Stores count as in split_program: each coordinate is written to q, qd and qdd.
    c.stores = 3 * static_cast<int>(st.plans[bi].block.cols.size());
    return c;
  });
}

}  // namespace

SolverPlan plan_block_solver(const SymbolicModel& model, const SymbolTable& symbols,
                             const Structure& st, int max_ops, int roll_min) {
  return plan_block_solver(model, symbols, st, build_block_program(model, symbols, st), max_ops,
                           roll_min);
}

SolverPlan plan_block_solver(const SymbolicModel& model, const SymbolTable& symbols,
                             const Structure& st, BlockProgram program, int max_ops, int roll_min) {
  SolverPlan sp;
  sp.structure = st;
  sp.program = std::move(program);
  const int nb = static_cast<int>(st.plans.size());
  sp.class_of.assign(nb, -1);
  sp.member_of.assign(nb, -1);
  if (roll_min > 0) find_repeated_blocks(sp, model, symbols, roll_min);
  if (max_ops > 0) split_blocks(sp, max_ops);
  return sp;
}

}  // namespace kinegen::codegen
