#include "kinegen/codegen/structure/structure.hpp"

#include <algorithm>
#include <map>
#include <utility>

namespace kinegen::codegen {

namespace {

// Compressed adjacency: the columns of each row.
struct Graph {
  std::vector<int> start, adj;
};

Graph row_graph(int nrows, const std::vector<int>& rows, const std::vector<int>& cols) {
  Graph g;
  g.start.assign(nrows + 1, 0);
  for (int r : rows) ++g.start[r + 1];
  for (int r = 0; r < nrows; ++r) g.start[r + 1] += g.start[r];
  g.adj.assign(rows.size(), 0);
  std::vector<int> fill(g.start.begin(), g.start.end() - 1);
  for (std::size_t k = 0; k < rows.size(); ++k) g.adj[fill[rows[k]]++] = cols[k];
  for (int r = 0; r < nrows; ++r)
    std::sort(g.adj.begin() + g.start[r], g.adj.begin() + g.start[r + 1]);
  return g;
}

// Maximum matching of rows to columns: a cheap greedy pass, then an iterative depth-first
// augmenting-path search per unmatched row (visited marks per search).
bool perfect_matching(const Graph& g, int nrows, int ncols, std::vector<int>& match_row,
                      std::vector<int>& match_col) {
  match_row.assign(nrows, -1);
  match_col.assign(ncols, -1);
  for (int r = 0; r < nrows; ++r)
    for (int k = g.start[r]; k < g.start[r + 1]; ++k)
      if (match_col[g.adj[k]] < 0) {
        match_col[g.adj[k]] = r;
        match_row[r] = g.adj[k];
        break;
      }
  std::vector<int> visited(ncols, -1), next(nrows), stack_rows, stack_cols;
  for (int root = 0; root < nrows; ++root) {
    if (match_row[root] >= 0) continue;
    stack_rows.assign(1, root);
    stack_cols.clear();
    next[root] = g.start[root];
    bool found = false;
    while (!stack_rows.empty() && !found) {
      const int r = stack_rows.back();
      if (next[r] == g.start[r + 1]) {
        stack_rows.pop_back();
        if (!stack_cols.empty()) stack_cols.pop_back();
        continue;
      }
      const int c = g.adj[next[r]++];
      if (visited[c] == root) continue;
      visited[c] = root;
      stack_cols.push_back(c);
      if (match_col[c] < 0) {
        found = true;
      } else {
        const int r2 = match_col[c];
        next[r2] = g.start[r2];
        stack_rows.push_back(r2);
      }
    }
    if (!found) return false;
    // stack_rows[i] takes stack_cols[i] along the path.
    for (std::size_t i = 0; i < stack_rows.size(); ++i) {
      match_row[stack_rows[i]] = stack_cols[i];
      match_col[stack_cols[i]] = stack_rows[i];
    }
  }
  return true;
}

// The next tear: the unknown found in most rows that cannot be solved for it (a coefficient
// that is not a non-zero number), then in most rows not yet used.
int choose_tear(const std::vector<char>& known, const std::vector<char>& used,
                const std::vector<std::vector<int>>& row_cols,
                const std::vector<std::vector<char>>& solvable,
                const std::vector<std::vector<int>>& col_rows) {
  const int k = static_cast<int>(known.size());
  int best = -1;
  long best_score = -1;
  for (int j = 0; j < k; ++j) {
    if (known[j]) continue;
    long hard = 0, all = 0;
    for (int i : col_rows[j]) {
      if (used[i]) continue;
      ++all;
      for (std::size_t a = 0; a < row_cols[i].size(); ++a)
        if (row_cols[i][a] == j && !solvable[i][a]) ++hard;
    }
    const long score = hard * (k + 1) + all;
    if (score > best_score) {
      best_score = score;
      best = j;
    }
  }
  return best;
}

// Tearing of a Newton block (greedy, as in Modelica tools): assign every row that has one
// unknown coordinate left and is linear in it with a constant coefficient; when none is left,
// make one unknown a tear variable (the one found in most rows that cannot be solved for it,
// then in most rows), and go on. Rows never assigned are the residuals. Newton then iterates
// on the tears only; the Schur complement of the assigned (triangular, constant-diagonal)
// part is the tears' Jacobian, and it is non-singular exactly when the block's is.
void tear_block(BlockPlan& plan, const SymbolicModel& model, const SymbolTable& symbols,
                const std::map<std::pair<int, int>, GiNaC::ex>& jac) {
  const Block& b = plan.block;
  const int k = static_cast<int>(b.rows.size());
  std::map<int, int> local;
  for (int j = 0; j < k; ++j) local[b.cols[j]] = j;
  std::vector<std::vector<int>> row_cols(k), col_rows(k);
  std::vector<std::vector<char>> solvable(k);
  for (int i = 0; i < k; ++i) {
    const auto first = jac.lower_bound({b.rows[i], -1});
    for (auto it = first; it != jac.end() && it->first.first == b.rows[i]; ++it) {
      const auto c = local.find(it->first.second);
      if (c == local.end()) continue;
      row_cols[i].push_back(c->second);
      col_rows[c->second].push_back(i);
      solvable[i].push_back(GiNaC::is_a<GiNaC::numeric>(it->second) && !it->second.is_zero());
    }
  }
  std::vector<char> known(k, 0), used(k, 0);
  std::vector<int> unknown(k), tears, order_rows, order_cols;
  for (int i = 0; i < k; ++i) unknown[i] = static_cast<int>(row_cols[i].size());
  std::vector<int> ready;
  const auto make_known = [&](int j) {
    known[j] = 1;
    for (int i : col_rows[j])
      if (--unknown[i] == 1 && !used[i]) ready.push_back(i);
  };
  for (int i = 0; i < k; ++i)
    if (unknown[i] == 1) ready.push_back(i);
  int n_known = 0;
  while (n_known < k) {
    while (!ready.empty()) {
      const int i = ready.back();
      ready.pop_back();
      if (used[i] || unknown[i] != 1) continue;
      for (std::size_t a = 0; a < row_cols[i].size(); ++a) {
        const int j = row_cols[i][a];
        if (known[j]) continue;
        if (solvable[i][a]) {
          used[i] = 1;
          order_rows.push_back(i);
          order_cols.push_back(j);
          make_known(j);
          ++n_known;
        }
        break;
      }
    }
    if (n_known == k) break;
    const int best = choose_tear(known, used, row_cols, solvable, col_rows);
    tears.push_back(best);
    make_known(best);
    ++n_known;
  }
  if (static_cast<int>(tears.size()) >= k) return;  // nothing gained
  for (int j : tears) plan.tears.push_back(b.cols[j]);
  for (int i = 0; i < k; ++i)
    if (!used[i]) plan.residuals.push_back(b.rows[i]);
  for (std::size_t a = 0; a < order_rows.size(); ++a) {
    const int r = b.rows[order_rows[a]], c = b.cols[order_cols[a]];
    const GiNaC::ex coefficient = jac.at({r, c});
    const GiNaC::ex& x = symbols.q(c);
    plan.assigned.push_back({r, c});
    plan.assigned_coefficient.push_back(coefficient);
    plan.assigned_value.push_back(-model.phi[r].subs(x == 0) / coefficient);
  }
}

}  // namespace

BltOrder blt_order(int nrows, int ncols, const std::vector<int>& rows,
                   const std::vector<int>& cols) {
  BltOrder out;
  if (nrows != ncols) return out;
  const Graph g = row_graph(nrows, rows, cols);
  std::vector<int> match_row, match_col;
  if (!perfect_matching(g, nrows, ncols, match_row, match_col)) return out;
  out.perfect = true;

  // Tarjan on rows: r -> match_col[c] for each column c of row r (r needs the coordinate that
  // row solves). Components come out dependencies first, which is the solve order.
  std::vector<int> index(nrows, -1), low(nrows, 0), next(nrows, 0), stack, call;
  std::vector<char> on_stack(nrows, 0);
  int counter = 0;
  for (int root = 0; root < nrows; ++root) {
    if (index[root] >= 0) continue;
    call.push_back(root);
    index[root] = low[root] = counter++;
    next[root] = g.start[root];
    stack.push_back(root);
    on_stack[root] = 1;
    while (!call.empty()) {
      const int r = call.back();
      if (next[r] < g.start[r + 1]) {
        const int w = match_col[g.adj[next[r]++]];
        if (index[w] < 0) {
          index[w] = low[w] = counter++;
          next[w] = g.start[w];
          stack.push_back(w);
          on_stack[w] = 1;
          call.push_back(w);
        } else if (on_stack[w]) {
          low[r] = std::min(low[r], index[w]);
        }
        continue;
      }
      call.pop_back();
      if (!call.empty()) low[call.back()] = std::min(low[call.back()], low[r]);
      if (low[r] != index[r]) continue;
      Block b;
      int w;
      do {
        w = stack.back();
        stack.pop_back();
        on_stack[w] = 0;
        b.rows.push_back(w);
        b.cols.push_back(match_row[w]);
      } while (w != r);
      std::sort(b.rows.begin(), b.rows.end());
      std::sort(b.cols.begin(), b.cols.end());
      out.blocks.push_back(std::move(b));
    }
  }
  out.row_block.assign(nrows, -1);
  out.col_block.assign(ncols, -1);
  for (std::size_t k = 0; k < out.blocks.size(); ++k) {
    for (int r : out.blocks[k].rows) out.row_block[r] = static_cast<int>(k);
    for (int c : out.blocks[k].cols) out.col_block[c] = static_cast<int>(k);
  }
  return out;
}

int Structure::explicit_count() const {
  int n = 0;
  for (const auto& p : plans) n += p.kind != BlockKind::kNewton;
  return n;
}

int Structure::newton_count() const { return static_cast<int>(plans.size()) - explicit_count(); }

int Structure::largest_newton() const {
  int n = 0;
  for (const auto& p : plans) n = std::max(n, p.newton_size());
  return n;
}

int Structure::largest_block() const {
  int n = 0;
  for (const auto& p : plans) n = std::max(n, static_cast<int>(p.block.rows.size()));
  return n;
}

const char* to_string(BlockKind kind) {
  switch (kind) {
    case BlockKind::kExplicit:
      return "explicit";
    case BlockKind::kExplicitGuarded:
      return "explicit (guarded)";
    case BlockKind::kNewton:
      return "newton";
  }
  return "?";
}

Structure analyze_structure(const SymbolicModel& model, const SymbolTable& symbols) {
  Structure s;
  std::vector<int> rows, cols;
  for (const auto& e : model.phi_q) {
    rows.push_back(e.row);
    cols.push_back(e.col);
  }
  s.order = blt_order(static_cast<int>(model.phi.size()), symbols.nq(), rows, cols);
  if (!s.order.perfect) return s;
  std::map<std::pair<int, int>, GiNaC::ex> jac;
  for (const auto& e : model.phi_q) jac[{e.row, e.col}] = e.value;
  for (const auto& b : s.order.blocks) {
    BlockPlan plan;
    plan.block = b;
    if (b.rows.size() == 1) {
      const GiNaC::ex& phi = model.phi[b.rows[0]];
      const GiNaC::ex& x = symbols.q(b.cols[0]);
      const GiNaC::ex expanded = phi.expand();
      if (expanded.is_polynomial(x) && expanded.degree(x) == 1) {
        // The derivative keeps the derived form (no expansion) and is free of x here.
        plan.coefficient = phi.diff(GiNaC::ex_to<GiNaC::symbol>(x)).normal();
        plan.rest = phi.subs(x == 0);
        if (!plan.coefficient.has(x)) {
          const bool constant =
              GiNaC::is_a<GiNaC::numeric>(plan.coefficient) && !plan.coefficient.is_zero();
          plan.kind = constant ? BlockKind::kExplicit : BlockKind::kExplicitGuarded;
        }
      }
    }
    if (plan.kind == BlockKind::kNewton && b.rows.size() > 1) tear_block(plan, model, symbols, jac);
    s.plans.push_back(std::move(plan));
  }
  return s;
}

}  // namespace kinegen::codegen
