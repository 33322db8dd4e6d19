// BlockEmitter (block_emitter.hpp): sin and cos of the coordinates: from the cache (_trig),
// rotated by Newton updates, and passed between a split block's functions in _sc.

#include <algorithm>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "block_emitter.hpp"

namespace kinegen::codegen::emit_detail {

// sin and cos of the block's angles: evaluated once at the start, then rotated by each
// Newton update (_rotate), and left in scope for the terms after the loop.
std::vector<int> BlockEmitter::declare_rotations(std::ostringstream& os, FunctionPrinter& pr,
                                                 const Block& b) {
  std::vector<int> rotated;
  for (int c : b.cols)
    if (declare_trig(os, pr, c, true)) rotated.push_back(c);
  return rotated;
}

// `T _sinC, _cosC` for a coordinate whose sin or cos the program uses, from the cache (see
// _trig); later terms read them. Explicit coordinates (always = false) only when the function
// being emitted needs them. Returns whether they were declared.
bool BlockEmitter::declare_trig(std::ostringstream& os, FunctionPrinter& pr, int c, bool always) {
  if (trig_slot_[c] < 0) return false;
  const auto needed = [&](int id) { return id >= 0 && (step_mode_ || in_position_[id]); };
  if (!always && !needed(sin_of_[c]) && !needed(cos_of_[c])) return false;
  const std::string s = "_sin" + idx(c), co = "_cos" + idx(c);
  if (sc_index_[c] >= 0 && split_sc_) {
    // In a split solver: in _sc, for the parts after this one.
    os << kIn << "[[maybe_unused]] T& " << s << " = _sc[" << sc_index_[c] << "];\n"
       << kIn << "[[maybe_unused]] T& " << co << " = _sc[" << sc_index_[c] + 1 << "];\n";
    sc_ready_[c] = 1;
  } else {
    os << kIn << "T " << s << ", " << co << ";\n";
  }
  os << kIn << "_trig(" << s << ", " << co << ", " << ref("q", c) << ", trig, "
     << (local_.empty() ? idx(trig_slot_[c]) : "_s[" + idx(trig_slot_[c]) + "]") << ");\n";
  if (sin_of_[c] >= 0) pr.bind(sin_of_[c], s);
  if (cos_of_[c] >= 0) pr.bind(cos_of_[c], co);
  return true;
}

// In a function that has the trig cache (motion_trig_): sin and cos, from the cache, of the
// coordinates block bi's rates read that are not yet in scope.
void BlockEmitter::declare_motion_trig(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                                       bool velocity, bool acceleration) {
  const BlockOuts& bo = blocks_[bi];
  std::vector<int> outputs = bo.jbb;
  for (const auto& [rc, o] : bo.tjac) outputs.push_back(o);
  for (const auto& row : bo.coupling)
    for (const auto& [c, o] : row) outputs.push_back(o);
  if (velocity) outputs.insert(outputs.end(), bo.nu.begin(), bo.nu.end());
  if (acceleration) outputs.insert(outputs.end(), bo.gamma.begin(), bo.gamma.end());
  declare_needed_trig(os, pr, outputs);
}

// sin and cos, from the cache, of the coordinates that `outputs` read through sin or cos and
// whose values are not yet in scope (a repeated block's coordinates, or an earlier part's).
void BlockEmitter::declare_needed_trig(std::ostringstream& os, FunctionPrinter& pr,
                                       const std::vector<int>& outputs) {
  std::vector<int> nodes;
  for (int o : outputs) nodes.push_back(out(o));
  for (int c : trig_read(pr, nodes)) trig_of(os, pr, c);
}

// The coordinates whose sin or cos the trees of `nodes` read and that are not yet in scope.
std::set<int> BlockEmitter::trig_read(FunctionPrinter& pr, const std::vector<int>& nodes) const {
  std::vector<int> stack = nodes;
  std::set<int> seen, coords;
  while (!stack.empty()) {
    const int id = stack.back();
    stack.pop_back();
    if (id == Program::kZero || pr.named(id) || !seen.insert(id).second) continue;
    const Node& n = prog_.nodes[id];
    if (n.kind == OpKind::kSin || n.kind == OpKind::kCos) {
      const Node& a = prog_.nodes[n.args[0]];
      if (a.kind == OpKind::kInput && a.input.kind == InputKind::kQ) {
        coords.insert(a.input.index);
        continue;
      }
    }
    for (int a : n.args) stack.push_back(a);
  }
  return coords;
}

// In a split torn block's functions: `T& _sinC = _sc[..]` (and _cosC) for its coordinates
// that `nodes` read or that are `updated`, then sin and cos from the cache of the other
// coordinates `nodes` read.
void BlockEmitter::torn_trig(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                             const std::vector<int>& nodes, const std::vector<int>& updated) {
  const TornParts& tp = torn_parts_[bi];
  std::set<int> coords = trig_read(pr, nodes);
  coords.insert(updated.begin(), updated.end());
  for (std::size_t i = 0; i < tp.rotated.size(); ++i) {
    const int c = tp.rotated[i];
    if (!coords.count(c)) continue;
    const int k = 2 * (tp.trig_first + static_cast<int>(i));
    os << kIn << "[[maybe_unused]] T& _sin" << c << " = _sc[" << k << "];\n"
       << kIn << "[[maybe_unused]] T& _cos" << c << " = _sc[" << k + 1 << "];\n";
    if (sin_of_[c] >= 0) pr.bind(sin_of_[c], "_sin" + idx(c));
    if (cos_of_[c] >= 0) pr.bind(cos_of_[c], "_cos" + idx(c));
  }
  for (int c : trig_read(pr, nodes)) trig_of(os, pr, c);
}

// A split torn block's own code (its Newton loop, or its rates): sin and cos (in the
// position first evaluated into _sc from the cache), and the terms of its residual rows that
// do not read its coordinates.
void BlockEmitter::torn_host_trig(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi,
                                  bool position) {
  const TornParts& tp = torn_parts_[bi];
  if (position && !tp.rotated.empty())
    os << kIn << "for (int _k = " << tp.trig_first << "; _k < "
       << tp.trig_first + static_cast<int>(tp.rotated.size()) << "; ++_k)\n"
       << kIn << "  _trig(_sc[2 * _k], _sc[2 * _k + 1], q[_torn_trig[_k][0]], trig, "
       << "_torn_trig[_k][1]);\n";
  if (position && !sc_ready_.empty())
    for (int c : tp.rotated) sc_ready_[c] = 1;
  const std::vector<int> host = torn_host_outputs(bi, position, !position);
  torn_trig(os, pr, bi, host, st_.plans[bi].tears);
  if (position)
    for (int id : host)
      pr.ensure(id, os, kIn, [&](int n) { return level_[n] < static_cast<int>(bi); });
}

void BlockEmitter::trig_of(std::ostringstream& os, FunctionPrinter& pr, int c) {
  if (sc_index_[c] < 0 || !split_sc_ || !sc_ready_[c]) {
    declare_trig(os, pr, c, true);
    return;
  }
  const std::string s = "_sin" + idx(c), co = "_cos" + idx(c);
  os << kIn << "[[maybe_unused]] T& " << s << " = _sc[" << sc_index_[c] << "];\n"
     << kIn << "[[maybe_unused]] T& " << co << " = _sc[" << sc_index_[c] + 1 << "];\n";
  if (sin_of_[c] >= 0) pr.bind(sin_of_[c], s);
  if (cos_of_[c] >= 0) pr.bind(cos_of_[c], co);
}

void BlockEmitter::bind_earlier_trig(std::ostringstream& os, FunctionPrinter& pr, std::size_t bi) {
  if (!split_sc_) return;
  const Block& b = st_.plans[bi].block;
  const int f = pos_first_[bi];
  const int end = bi + 1 < st_.plans.size() ? pos_first_[bi + 1] : pos_end_;
  std::vector<int> nodes;
  for (int o = f; o < end; ++o) nodes.push_back(out(o));
  for (const auto& [rc, o] : pos_tjac_[bi]) nodes.push_back(out(o));
  for (const auto& row : blocks_[bi].coupling)
    for (const auto& [col, o] : row) nodes.push_back(out(o));
  for (int o : blocks_[bi].jbb) nodes.push_back(out(o));
  for (int c : trig_read(pr, nodes))
    if (sc_ready_[c] && !std::binary_search(b.cols.begin(), b.cols.end(), c)) trig_of(os, pr, c);
}

}  // namespace kinegen::codegen::emit_detail
