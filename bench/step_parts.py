#!/usr/bin/env python3
"""Code-footprint experiment for a split block solver (docs/scale.md, "Step time from N = 100
to N = 1000"). Writes a C++ program that times a full solve_step and, separately, each of its
parts (_solve_position_part<k>, _solve_velocity_acceleration_part<k>) run 200 times in a row so
that its code stays cached, with BlockOptions::fixed_iterations = 2 for the same work each
time. If the sum of the warm parts grows linearly but the full step does not, the difference
is code fetch. Not a test.

  bench/step_parts.py HEADER MODEL OUT.cpp && g++ -O2 -std=c++17 OUT.cpp -o parts && ./parts
"""
import re
import sys

header, model, out = sys.argv[1:4]
text = open(header).read()
calls = []
for k in sorted({int(m) for m in re.findall(r"static BlockReport _solve_position_part(\d+)\(", text)}):
    calls.append(f"[&] {{ return M::_solve_position_part{k}(q.data(), t, p, o, M::BlockReport{{}}); }}")
for k in sorted({int(m) for m in re.findall(
        r"static BlockReport _solve_velocity_acceleration_part(\d+)\(", text)}):
    calls.append(f"[&] {{ return M::_solve_velocity_acceleration_part{k}(q.data(), t, p, "
                 f"qd.data(), qdd.data(), o, M::BlockReport{{}}); }}")
if not calls:
    sys.exit("error: " + header + " has no split block solver (generate with a larger N)")
joined = ",\n      ".join(calls)
open(out, "w").write(f'''// Written by bench/step_parts.py: full solve_step vs its parts run warm. Not a test.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <vector>
#define private public  // the parts are private members
#include "{header}"
#undef private
using M = kinegen::models::{model};
int main() {{
  const M::Params p{{}};
  M::BlockOptions o{{}};
  std::vector<double> q(M::q0.begin(), M::q0.end()), qd(M::nq), qdd(M::nq);
  const double t = 0.3;
  if (M::solve_step(q.data(), t, p, qd.data(), qdd.data(), o).status != 0) return 1;
  o.fixed_iterations = 2;
  using Clock = std::chrono::steady_clock;
  const auto ns = [](Clock::time_point a, Clock::time_point b) {{
    return std::chrono::duration<double, std::nano>(b - a).count();
  }};
  double full = 1e300;
  for (int rep = 0; rep < 5; ++rep) {{
    const auto a = Clock::now();
    for (int k = 0; k < 200; ++k) M::solve_step(q.data(), t, p, qd.data(), qdd.data(), o);
    full = std::min(full, ns(a, Clock::now()) / 200);
  }}
  std::vector<std::function<M::BlockReport()>> parts = {{
      {joined}}};
  double sum = 0;
  for (auto& f : parts) {{
    double best = 1e300;
    for (int rep = 0; rep < 5; ++rep) {{
      const auto a = Clock::now();
      for (int k = 0; k < 200; ++k) f();
      best = std::min(best, ns(a, Clock::now()) / 200);
    }}
    sum += best;
  }}
  std::printf("nq %d parts %zu full_step_ns %.0f sum_of_warm_parts_ns %.0f\\n", M::nq,
              parts.size(), full, sum);
}}
''')
