// One rule for threads. GiNaC and CLN keep state that every thread shares (reference counts
// of shared expressions, the unique symbols and numbers, caches, the Digits setting), without
// locks, so the generator library (kinegen_codegen: loading, deriving, lowering, emitting,
// analysing, checking, simulating, and destroying a CompiledModel) is not thread-safe. A
// program that calls it from several threads holds library_mutex() around every call; the
// Python module does so in every method (python/kinegen_module.cpp, `Locked`). The mutex is
// recursive, so that a call made while it is held (a destructor run by a callback) does not
// deadlock its own thread.
//
// Generated headers and the runtime (kinegen::Solver, kinegen/solver.hpp) share nothing between
// objects: no static or global state, so each thread may run its own Solver without a lock
// (tests/test_threads.cpp runs eight).
#pragma once

#include <mutex>

namespace kinegen::codegen {

inline std::recursive_mutex& library_mutex() {
  static std::recursive_mutex mutex;
  return mutex;
}

}  // namespace kinegen::codegen
