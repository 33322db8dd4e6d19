// Locked (locked.hpp): the GIL released, the library's lock held, signals checked.
#include "locked.hpp"

#include <pybind11/pybind11.h>
#include <pythread.h>

#include <chrono>

#include "kinegen/codegen/base/library_lock.hpp"

namespace py = pybind11;
namespace kc = kinegen::codegen;

namespace kinegen::python {

namespace {

unsigned long g_main_thread = 0;

// A library interruption point: at most every 20 ms, on the main thread (the only one where
// Python runs signal handlers), take the GIL and run the pending handlers. This thread holds
// the library's lock; taking the GIL here cannot deadlock because no thread waits for the lock
// while holding the GIL (Locked's order).
void check_signals() {
  using Clock = std::chrono::steady_clock;
  thread_local Clock::time_point next{};
  const Clock::time_point now = Clock::now();
  if (now < next) return;
  next = now + std::chrono::milliseconds(20);
  if (PyThread_get_thread_ident() != g_main_thread) return;
  py::gil_scoped_acquire gil;
  if (PyErr_CheckSignals() != 0) throw kc::Interrupted("KeyboardInterrupt");
}

}  // namespace

void init_signal_checks() {
  g_main_thread =
      py::module_::import("threading").attr("main_thread")().attr("ident").cast<unsigned long>();
}

Locked::Locked(bool interruptible)
    : saved_(PyGILState_Check() ? PyEval_SaveThread() : nullptr), lock_(kc::library_mutex()) {
  if (interruptible) hook_.emplace(check_signals);
}

Locked::~Locked() {
  hook_.reset();
  lock_.unlock();
  if (saved_) PyEval_RestoreThread(saved_);
}

}  // namespace kinegen::python
