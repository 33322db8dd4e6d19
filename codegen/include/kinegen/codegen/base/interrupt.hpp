// Stopping a long run from outside (Ctrl-C): the loops that can run long call
// interruption_point() (each row of an analysis or a simulation, each Monte Carlo sample, each
// derivative check's sample, each equation the symbolic stage derives, each line of a run's
// CSV), which throws Interrupted when a stop was asked for. The library installs no signal
// handler: the command line sets the process' flag from its SIGINT handler
// (io/output_file.hpp: install_signal_handlers), and the Python module gives each call a hook
// of its own (a ScopedInterruptHook that runs PyErr_CheckSignals). Interrupted unwinds like
// any error; a caller that streams rows (analyze, simulate) keeps those written.
#pragma once

#include <functional>
#include <stdexcept>
#include <string>

namespace kinegen::codegen {

// A run stopped by interruption_point(). The command line's exit status 130 (128 + SIGINT).
class Interrupted : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Throws Interrupted when this thread's hook says so, or, without a hook, when the process'
// flag is set (request_interrupt). Cheap: a thread-local load and an atomic one.
void interruption_point();

// Asks every run without a hook of its own to stop at its next interruption point. Async-signal
// safe: a signal handler calls it.
void request_interrupt() noexcept;
bool interrupt_requested() noexcept;

// While alive, interruption_point() on this thread calls `hook` (which throws Interrupted, or
// anything else, to stop the run) instead of reading the process' flag. Nests: the previous
// hook comes back on destruction.
class ScopedInterruptHook {
 public:
  explicit ScopedInterruptHook(std::function<void()> hook);
  ~ScopedInterruptHook();
  ScopedInterruptHook(const ScopedInterruptHook&) = delete;
  ScopedInterruptHook& operator=(const ScopedInterruptHook&) = delete;

 private:
  std::function<void()> hook_;
  const std::function<void()>* previous_;
};

}  // namespace kinegen::codegen
