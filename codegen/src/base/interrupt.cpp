#include "kinegen/codegen/base/interrupt.hpp"

#include <atomic>

namespace kinegen::codegen {

namespace {

// Lock-free, so that a signal handler may store it.
std::atomic<bool> g_requested{false};
static_assert(std::atomic<bool>::is_always_lock_free);

thread_local const std::function<void()>* t_hook = nullptr;

}  // namespace

void interruption_point() {
  if (t_hook) {
    (*t_hook)();
    return;
  }
  if (g_requested.load(std::memory_order_relaxed)) throw Interrupted("interrupted");
}

void request_interrupt() noexcept { g_requested.store(true, std::memory_order_relaxed); }

bool interrupt_requested() noexcept { return g_requested.load(std::memory_order_relaxed); }

ScopedInterruptHook::ScopedInterruptHook(std::function<void()> hook)
    : hook_(std::move(hook)), previous_(t_hook) {
  t_hook = &hook_;
}

ScopedInterruptHook::~ScopedInterruptHook() { t_hook = previous_; }

}  // namespace kinegen::codegen
