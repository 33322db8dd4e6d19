// The one rule for threads in the Python module (codegen/base/library_lock.hpp): every method
// that reaches the library (GiNaC, CLN, files it writes, a CompiledModel's destruction) does
// that work inside a `Locked` scope, and touches no Python object there:
//
//   return translate(path_, [&] {
//     Locked locked;  // the GIL released, the library's lock held, Ctrl-C watched
//     ...library calls on plain C++ values...
//   });
//   ...Python objects built from the results, with the GIL...
//
// Locked releases the GIL first and only then waits for the library's lock, never the
// reverse: a thread waiting for the lock never holds the GIL, so the holder of the lock can
// always take the GIL back (to check for Ctrl-C) and nothing deadlocks. While it runs, the
// library's interruption points (base/interrupt.hpp) call PyErr_CheckSignals on the main
// thread every 20 ms; a KeyboardInterrupt (or any exception a signal handler raises) stops the
// call, and translate() raises it in Python.
#pragma once

#include <Python.h>

#include <mutex>
#include <optional>

#include "kinegen/codegen/base/interrupt.hpp"

namespace kinegen::python {

class Locked {
 public:
  // interruptible = false where nothing may throw (a destructor).
  explicit Locked(bool interruptible = true);
  ~Locked();
  Locked(const Locked&) = delete;
  Locked& operator=(const Locked&) = delete;

 private:
  PyThreadState* saved_;  // this thread's state while the GIL is released; null if not held
  std::unique_lock<std::recursive_mutex> lock_;
  std::optional<codegen::ScopedInterruptHook> hook_;
};

// Records the interpreter's main thread (where signal handlers run); at module import.
void init_signal_checks();

}  // namespace kinegen::python
