// The tangent of the minimal-coordinates dynamics, the symbolic half (see symbolic/tangent.hpp).
#include "kinegen/codegen/symbolic/tangent.hpp"

#include <map>

#include "kinegen/codegen/symbolic/functions.hpp"
#include "symbolic_detail.hpp"

namespace kinegen::codegen {

namespace {

using GiNaC::ex;
using symbolic_detail::naming_errors;
using symbolic_detail::row_loc;

// The coordinates (kQ) or velocities (kQd) `e` reads, ascending.
std::vector<int> read_by(const ex& e, const SymbolTable& s, InputKind kind) {
  std::vector<bool> seen(s.nq(), false);
  for (auto it = e.preorder_begin(); it != e.preorder_end(); ++it)
    if (GiNaC::is_a<GiNaC::symbol>(*it)) {
      const Input in = s.classify(*it);
      if (in.kind == kind) seen[in.index] = true;
    }
  std::vector<int> out;
  for (int k = 0; k < s.nq(); ++k)
    if (seen[k]) out.push_back(k);
  return out;
}

// The run-time inputs `e` reads, by slot (3 driver + order; a load's input as a driver past
// the last), with the kinegen_input each is.
std::map<int, ex> inputs_in(const ex& e) {
  std::map<int, ex> found;
  for (auto it = e.preorder_begin(); it != e.preorder_end(); ++it) {
    int driver = 0, order = 0;
    if (is_input(*it, driver, order)) found.emplace(3 * driver + order, *it);
  }
  return found;
}

// d e / d(input): the input replaced by a symbol, differentiated, and put back.
ex diff_input(const ex& e, const ex& input) {
  const GiNaC::realsymbol w("w");
  return e.subs(input == w).diff(w).subs(w == input);
}

SparseExpr sparse(int rows, int cols) {
  SparseExpr m;
  m.rows = rows;
  m.cols = cols;
  return m;
}

// Row r of `of` differentiated by what it reads of `kind` (coordinates or velocities).
void add_row(SparseExpr& out, int r, const ex& e, const SymbolTable& s, InputKind kind) {
  for (int k : read_by(e, s, kind)) out.add(r, k, e.diff(kind == InputKind::kQ ? s.q(k) : s.qd(k)));
}

void add_input_row(SparseExpr& out, int r, const ex& e) {
  for (const auto& [slot, input] : inputs_in(e)) out.add(r, slot, diff_input(e, input));
}

const char* const kCannotForm = "its second derivatives cannot be formed";

// Runs f for Phi's row r, naming its item.
template <class F>
void for_row(const Mechanism& m, const SymbolicModel& model, int r, F&& f) {
  const Constraint& c = *model.rows[r].constraint;
  naming_errors(m, c.item, row_loc(c, model.rows[r].component), kCannotForm, f);
}

// Runs f for coordinate k's applied force, naming its body (or extra coordinate).
template <class F>
void for_coordinate(const Mechanism& m, int k, F&& f) {
  const int nb = static_cast<int>(m.bodies.size());
  const bool body = k < 3 * nb;
  const std::string& name = body ? m.bodies[k / 3].name : m.coordinates[k - 3 * nb].name;
  const SourceLoc loc = body ? m.bodies[k / 3].loc : m.coordinates[k - 3 * nb].loc;
  naming_errors(m, std::string(body ? "body '" : "coordinate '") + name + "' (its forces)", loc,
                kCannotForm, f);
}

}  // namespace

TangentModel derive_tangent(const Mechanism& m, const SymbolTable& s, const SymbolicModel& model,
                            const ForceModel& forces) {
  const int nc = static_cast<int>(model.phi.size()), nq = s.nq(), slots = m.input_slots();
  TangentModel t;
  // Phi_qq from Phi_q's entries: the entry (r, j) by each coordinate k >= j it reads (an
  // entry that reads q_k < j is the symmetric (r, k, j), found from entry (r, k)).
  for (const JacobianEntry& e : model.phi_q)
    for_row(m, model, e.row, [&] {
      for (int k : read_by(e.value, s, InputKind::kQ)) {
        if (k < e.col) continue;
        const ex d = e.value.diff(s.q(k));
        if (d.is_zero()) continue;
        t.phi_qq.row.push_back(e.row);
        t.phi_qq.j.push_back(e.col);
        t.phi_qq.k.push_back(k);
        t.phi_qq.value.push_back(d);
      }
    });
  t.nu_q = t.gamma_q = t.gamma_qd = sparse(nc, nq);
  t.phi_w = t.nu_w = t.gamma_w = sparse(nc, slots);
  for (int r = 0; r < nc; ++r)
    for_row(m, model, r, [&] {
      add_row(t.nu_q, r, model.nu[r], s, InputKind::kQ);
      add_row(t.gamma_q, r, model.gamma[r], s, InputKind::kQ);
      add_row(t.gamma_qd, r, model.gamma[r], s, InputKind::kQd);
      add_input_row(t.phi_w, r, model.phi[r]);
      add_input_row(t.nu_w, r, model.nu[r]);
      add_input_row(t.gamma_w, r, model.gamma[r]);
    });
  t.applied_q = t.applied_qd = sparse(nq, nq);
  t.applied_w = sparse(nq, slots);
  for (int k = 0; k < nq; ++k)
    for_coordinate(m, k, [&] {
      add_row(t.applied_q, k, forces.applied[k], s, InputKind::kQ);
      add_row(t.applied_qd, k, forces.applied[k], s, InputKind::kQd);
      add_input_row(t.applied_w, k, forces.applied[k]);
    });
  return t;
}

}  // namespace kinegen::codegen
