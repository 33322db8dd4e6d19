// Repeated pieces: constraints (their outputs) and blocks that are the same up to which
// coordinates they read, the loops of a chain. They are compared under a renaming of the
// coordinates they read: the k-th coordinate of a piece's table becomes the model's k-th, q and
// qd alike. The emitter writes each class once, as a function called with each member's table
// (EmitOptions::roll_min); structure/solver_plan.hpp finds the repeated blocks.
#pragma once

#include <ginac/ginac.h>

#include <map>
#include <set>
#include <string>
#include <vector>

#include "kinegen/codegen/program/program.hpp"
#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen {

// Adds the coordinates whose q or qd `e` reads to `read`.
void add_coordinates_read(const GiNaC::ex& e, const SymbolTable& symbols, std::set<int>& read);

// table[k] -> coordinate k, q and qd alike; one substitution, so the renaming is simultaneous.
GiNaC::exmap table_renaming(const std::vector<int>& table, const SymbolTable& symbols);

// Equal printed keys should mean equal renamed expressions, but names could coincide: this
// compares exactly.
bool same_expressions(const std::vector<GiNaC::ex>& a, const std::vector<GiNaC::ex>& b);

// The groups of pieces found under each printed key, in the order of their first members: the
// printed keys order by GiNaC's hashes, which change from process to process (address-space
// layout randomization), and the classes' order reaches the generated code.
std::vector<std::vector<int>> by_first_member(std::map<std::string, std::vector<int>> by_key);

// Section-4 functions with repeated constraints (EmitOptions::roll_min): the outputs of each
// constraint form a group; groups alike up to the coordinates they read (with the k-th
// coordinate read, ascending, renamed to the model's k-th, q and qd alike, every output is the
// same expression) are evaluated by one function, in a loop over tables of their coordinates
// and output indices. The rest is lowered and emitted as usual.
struct RolledOutputs {
  struct Class {
    Program program;                       // the first group's outputs
    std::vector<int> slot;                 // coordinate -> its slot in the first group's table
    std::vector<std::vector<int>> coords;  // per group: coordinates read, ascending
    std::vector<std::vector<int>> outs;    // per group: its out indices
  };
  std::vector<Class> classes;
  Program rest;                 // the outputs of no class
  std::vector<int> rest_index;  // their out indices
};

RolledOutputs roll_outputs(const std::vector<GiNaC::ex>& exprs, const std::vector<int>& group,
                           const SymbolTable& symbols, int roll_min);

}  // namespace kinegen::codegen
