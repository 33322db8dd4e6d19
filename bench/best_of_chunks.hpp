// The benchmarks' timer: work timed in short chunks that continue one trajectory, the best
// chunk counting, so that other processes on a shared machine disturb the figures as little
// as possible.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>

namespace kinegen::bench {

// Best time per call over `chunks` chunks of `chunk_size` calls; `chunk(k0)` does calls k0 ..
// k0 + chunk_size - 1 and returns false on a failure (the result is then NaN).
template <class Chunk>
double best_ns(int chunks, int chunk_size, Chunk&& chunk) {
  double best = 1e300;
  for (int c = 0; c < chunks; ++c) {
    const auto start = std::chrono::steady_clock::now();
    if (!chunk(c * chunk_size)) return NAN;
    const auto stop = std::chrono::steady_clock::now();
    best =
        std::min(best, std::chrono::duration<double, std::nano>(stop - start).count() / chunk_size);
  }
  return best;
}

}  // namespace kinegen::bench
