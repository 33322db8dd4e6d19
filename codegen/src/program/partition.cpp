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

}  // namespace kinegen::codegen
