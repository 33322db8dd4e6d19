#include "kinegen/codegen/structure/block_program.hpp"

namespace kinegen::codegen {

std::map<int, std::vector<char>> tear_dependency(
    const BlockPlan& plan, const std::map<std::pair<int, int>, int>& entries) {
  const std::size_t m = plan.tears.size();
  std::map<int, std::vector<char>> dep;
  for (std::size_t j = 0; j < m; ++j) {
    dep[plan.tears[j]].assign(m, 0);
    dep[plan.tears[j]][j] = 1;
  }
  for (const auto& [r, c] : plan.assigned) {
    std::vector<char> d(m, 0);
    for (const auto& [rc, o] : entries)
      if (rc.first == r && rc.second != c)
        for (std::size_t j = 0; j < m; ++j) d[j] |= dep.at(rc.second)[j];
    dep[c] = d;
  }
  return dep;
}

namespace {

// Per node of the lowered program: its level (the last block it reads), whether the position
// reads it; per coordinate: its sin and cos nodes and its trig cache slot.
void index_nodes(BlockProgram& bp, const Structure& st) {
  const Program& prog = bp.program;
  bp.level.assign(prog.nodes.size(), -1);
  for (std::size_t k = 0; k < prog.nodes.size(); ++k) {
    const Node& n = prog.nodes[k];
    if (n.kind == OpKind::kInput && n.input.kind == InputKind::kQ)
      bp.level[k] = st.order.col_block[n.input.index];
    for (int a : n.args) bp.level[k] = std::max(bp.level[k], bp.level[a]);
  }
  // sin and cos nodes of each coordinate, for the rotation update in Newton loops.
  const int nq = static_cast<int>(st.order.col_block.size());
  bp.sin_of.assign(nq, -1);
  bp.cos_of.assign(nq, -1);
  for (std::size_t k = 0; k < prog.nodes.size(); ++k) {
    const Node& n = prog.nodes[k];
    if (n.kind != OpKind::kSin && n.kind != OpKind::kCos) continue;
    const Node& a = prog.nodes[n.args[0]];
    if (a.kind != OpKind::kInput || a.input.kind != InputKind::kQ) continue;
    (n.kind == OpKind::kSin ? bp.sin_of : bp.cos_of)[a.input.index] = static_cast<int>(k);
  }
  bp.trig_slot.assign(nq, -1);
  for (int c = 0; c < nq; ++c)
    if (bp.sin_of[c] >= 0 || bp.cos_of[c] >= 0) bp.trig_slot[c] = bp.trig_slots++;
  bp.in_position.assign(prog.nodes.size(), 0);
  for (int o = 0; o < bp.position_end; ++o)
    if (bp.output(o) != Program::kZero) bp.in_position[bp.output(o)] = 1;
  for (int k = static_cast<int>(prog.nodes.size()) - 1; k >= 0; --k)
    if (bp.in_position[k])
      for (int a : prog.nodes[k].args) bp.in_position[a] = 1;
}

}  // namespace

BlockProgram build_block_program(const SymbolicModel& model, const SymbolTable& symbols,
                                 const Structure& st) {
  BlockProgram bp;
  std::map<std::pair<int, int>, GiNaC::ex> jac;
  for (const auto& e : model.phi_q) jac[{e.row, e.col}] = e.value;
  std::vector<GiNaC::ex>& outs = bp.exprs;
  const auto add = [&](const GiNaC::ex& e) {
    outs.push_back(e);
    return static_cast<int>(outs.size()) - 1;
  };
  const auto jac_at = [&](int r, int c) {
    const auto it = jac.find({r, c});
    return it == jac.end() ? GiNaC::ex(0) : it->second;
  };
  for (const auto& plan : st.plans) {
    bp.position_first.push_back(static_cast<int>(outs.size()));
    const Block& b = plan.block;
    switch (plan.kind) {
      case BlockKind::kExplicit:
        add(-plan.rest / plan.coefficient);
        break;
      case BlockKind::kExplicitGuarded:
        add(plan.coefficient);
        add(plan.rest);
        break;
      case BlockKind::kNewton:
        if (plan.torn()) {
          for (const GiNaC::ex& v : plan.assigned_value) add(v);
          for (int r : plan.residuals) add(model.phi[r]);
          std::map<std::pair<int, int>, int> entries;
          for (int r : b.rows)
            for (int c : b.cols)
              if (jac.count({r, c})) entries[{r, c}] = add(jac_at(r, c));
          bp.torn_jacobian.push_back(std::move(entries));
          break;
        }
        for (int r : b.rows) add(model.phi[r]);
        for (int r : b.rows)
          for (int c : b.cols) add(jac_at(r, c));
        break;
    }
    if (!plan.torn()) bp.torn_jacobian.emplace_back();
  }
  bp.position_end = static_cast<int>(outs.size());
  std::vector<std::vector<const JacobianEntry*>> row_entries(model.phi.size());
  for (const auto& e : model.phi_q) row_entries[e.row].push_back(&e);
  for (std::size_t bi = 0; bi < st.plans.size(); ++bi) {
    const Block& b = st.plans[bi].block;
    BlockRates bo;
    const bool torn = st.plans[bi].torn();
    for (int r : b.rows) {
      for (int c : b.cols) {
        if (!torn)
          bo.jbb.push_back(add(jac_at(r, c)));
        else if (jac.count({r, c}))
          bo.tjac[{r, c}] = add(jac_at(r, c));
      }
      std::vector<std::pair<int, int>> coupling;
      for (const JacobianEntry* e : row_entries[r])
        if (st.order.col_block[e->col] < static_cast<int>(bi))
          coupling.push_back({e->col, add(e->value)});
      bo.coupling.push_back(coupling);
      bo.nu.push_back(add(model.nu[r]));
      bo.gamma.push_back(add(model.gamma[r]));
    }
    bp.rates.push_back(bo);
  }
  bp.program = lower(outs, symbols);
  index_nodes(bp, st);
  return bp;
}

}  // namespace kinegen::codegen
