#include "kinegen/codegen/program/partition.hpp"

namespace kinegen::codegen {

PartRanges partition(const Program& program, int max_ops, int n,
                     const std::function<PartCost(int)>& cost) {
  const int max_stores = max_part_outputs(max_ops);
  PartRanges ranges;
  std::vector<int> part_of(program.nodes.size(), -1), stack;
  int ops = 0, stores = 0, first = 0;
  for (int item = 0; item < n; ++item) {
    const int part = static_cast<int>(ranges.size());
    const PartCost c = cost(item);
    ops += c.ops;
    stores += c.stores;
    for (int id : c.nodes) {
      if (id == Program::kZero || part_of[id] == part) continue;
      stack.assign(1, id);
      part_of[id] = part;
      while (!stack.empty()) {
        const Node& node = program.nodes[stack.back()];
        stack.pop_back();
        ops += node.kind != OpKind::kConst && node.kind != OpKind::kInput;
        for (int a : node.args)
          if (part_of[a] != part) {
            part_of[a] = part;
            stack.push_back(a);
          }
      }
    }
    if (ops >= max_ops || stores >= max_stores || item + 1 == n) {
      ranges.push_back({first, item + 1});
      first = item + 1;
      ops = 0;
      stores = 0;
    }
  }
  return ranges;
}

std::vector<ProgramPart> split_program(const Program& program, int max_ops) {
  const PartRanges ranges =
      partition(program, max_ops, static_cast<int>(program.outputs.size()), [&](int o) {
        return PartCost{{program.outputs[o]}, 0, 1};
      });
  std::vector<ProgramPart> parts;
  std::vector<int> part_of(program.nodes.size(), -1);
  std::vector<int> stack;
  for (const auto& [first, last] : ranges) {
    const int part = static_cast<int>(parts.size());
    ProgramPart pp;
    pp.first_output = first;
    std::vector<int> members;
    std::vector<int> outs;
    for (int o = first; o < last; ++o) {
      const int id = program.outputs[o];
      outs.push_back(id);
      if (id == Program::kZero || part_of[id] == part) continue;
      stack.assign(1, id);
      part_of[id] = part;
      while (!stack.empty()) {
        const int k = stack.back();
        stack.pop_back();
        members.push_back(k);
        for (int a : program.nodes[k].args)
          if (part_of[a] != part) {
            part_of[a] = part;
            stack.push_back(a);
          }
      }
    }
    std::sort(members.begin(), members.end());
    std::vector<int> remap(program.nodes.size(), -1);
    for (int k : members) {
      remap[k] = static_cast<int>(pp.program.nodes.size());
      Node n = program.nodes[k];
      for (int& a : n.args) a = remap[a];
      pp.program.nodes.push_back(std::move(n));
    }
    for (int id : outs) pp.program.outputs.push_back(id == Program::kZero ? id : remap[id]);
    parts.push_back(std::move(pp));
  }
  return parts;
}

}  // namespace kinegen::codegen
