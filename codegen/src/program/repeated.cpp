#include "kinegen/codegen/program/repeated.hpp"

#include <algorithm>
#include <map>
#include <sstream>
#include <string>

namespace kinegen::codegen {

std::vector<std::vector<int>> by_first_member(std::map<std::string, std::vector<int>> by_key) {
  std::vector<std::vector<int>> classes;
  for (auto& entry : by_key) classes.push_back(std::move(entry.second));
  std::sort(classes.begin(), classes.end());  // disjoint and ascending: by their first members
  return classes;
}

// Adds the coordinates whose q or qd `e` reads to `read`.
void add_coordinates_read(const GiNaC::ex& e, const SymbolTable& symbols, std::set<int>& read) {
  for (auto it = e.preorder_begin(); it != e.preorder_end(); ++it)
    if (GiNaC::is_a<GiNaC::symbol>(*it)) {
      const Input in = symbols.classify(*it);
      if (in.kind == InputKind::kQ || in.kind == InputKind::kQd) read.insert(in.index);
    }
}

// table[k] -> coordinate k, q and qd alike; one substitution, so the renaming is simultaneous.
GiNaC::exmap table_renaming(const std::vector<int>& table, const SymbolTable& symbols) {
  GiNaC::exmap rename;
  for (std::size_t k = 0; k < table.size(); ++k) {
    rename[symbols.q(table[k])] = symbols.q(static_cast<int>(k));
    rename[symbols.qd(table[k])] = symbols.qd(static_cast<int>(k));
  }
  return rename;
}

// Equal printed keys should mean equal renamed expressions, but names could coincide: this
// compares exactly.
bool same_expressions(const std::vector<GiNaC::ex>& a, const std::vector<GiNaC::ex>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t k = 0; k < a.size(); ++k)
    if (!a[k].is_equal(b[k])) return false;
  return true;
}

RolledOutputs roll_outputs(const std::vector<GiNaC::ex>& exprs, const std::vector<int>& group,
                           const SymbolTable& symbols, int roll_min) {
  RolledOutputs ro;
  std::map<int, std::vector<int>> members;  // group -> its outputs, in order
  for (std::size_t k = 0; k < exprs.size(); ++k) members[group[k]].push_back(static_cast<int>(k));
  std::map<std::string, std::vector<int>> alike;  // key -> groups
  std::map<int, std::vector<int>> coords;
  std::map<int, std::vector<GiNaC::ex>> renamed;
  for (const auto& [g, outs] : members) {
    std::set<int> read;
    for (int k : outs) add_coordinates_read(exprs[k], symbols, read);
    const std::vector<int> list(read.begin(), read.end());
    const GiNaC::exmap rename = table_renaming(list, symbols);
    std::ostringstream key;
    key << outs.size() << " " << list.size();
    for (int k : outs) {
      renamed[g].push_back(exprs[k].subs(rename));
      key << " " << renamed[g].back() << ";";
    }
    coords[g] = list;
    alike[key.str()].push_back(g);
  }
  std::vector<char> rolled(exprs.size(), 0);
  for (const std::vector<int>& groups : by_first_member(std::move(alike))) {
    if (static_cast<int>(groups.size()) < roll_min) continue;
    const int first = groups[0];
    RolledOutputs::Class c;
    for (int g : groups) {
      if (coords[g].size() != coords[first].size() || !same_expressions(renamed[g], renamed[first]))
        continue;
      c.coords.push_back(coords[g]);
      c.outs.push_back(members[g]);
    }
    if (static_cast<int>(c.outs.size()) < roll_min) continue;
    for (const auto& outs : c.outs)
      for (int k : outs) rolled[k] = 1;
    std::vector<GiNaC::ex> first_exprs;
    for (int k : members[first]) first_exprs.push_back(exprs[k]);
    c.program = lower(first_exprs, symbols);
    c.slot.assign(symbols.nq(), -1);
    for (std::size_t j = 0; j < coords[first].size(); ++j)
      c.slot[coords[first][j]] = static_cast<int>(j);
    ro.classes.push_back(std::move(c));
  }
  std::vector<GiNaC::ex> rest;
  for (std::size_t k = 0; k < exprs.size(); ++k)
    if (!rolled[k]) {
      rest.push_back(exprs[k]);
      ro.rest_index.push_back(static_cast<int>(k));
    }
  ro.rest = lower(rest, symbols);
  return ro;
}

}  // namespace kinegen::codegen
