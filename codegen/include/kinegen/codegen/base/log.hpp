// The command line's messages on standard error besides errors: warnings, the "wrote" line,
// stage progress and timings. Library code does not print: it reports its stages through a
// Progress callback (progress.hpp), which Log::progress_callbacks() turns into these lines. Only
// the command line (codegen/src/cli/) includes this header; it sets the log up once:
//   quiet   - errors only (they do not go through here);
//   normal  - warnings and results; stage progress only when stderr is a terminal;
//   verbose - as normal, plus every stage with its time and size, terminal or not.
// On a terminal a stage that runs longer than a moment shows a ticking elapsed time, so a long
// derivation of a large mechanism is visibly alive.
#pragma once

#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>

#include "kinegen/codegen/base/progress.hpp"

namespace kinegen::codegen {

enum class Verbosity { kQuiet, kNormal, kVerbose };

class Log {
 public:
  static Log& global() {
    static Log log;
    return log;
  }
  Log(const Log&) = delete;
  Log& operator=(const Log&) = delete;
  ~Log() { end_stage(""); }

  void set_verbosity(Verbosity v) { verbosity_ = v; }
  Verbosity verbosity() const { return verbosity_; }
  // Whether stage progress is shown (terminal or --verbose, never --quiet).
  bool progress() const {
    return verbosity_ == Verbosity::kVerbose || (verbosity_ == Verbosity::kNormal && tty_);
  }

  void warning(const std::string& message) {
    if (verbosity_ == Verbosity::kQuiet) return;
    std::lock_guard<std::mutex> lock(mutex_);
    clear_line_locked();
    std::fprintf(stderr, "warning: %s\n", message.c_str());
  }
  // A result worth one line (what was written).
  void info(const std::string& message) {
    if (verbosity_ == Verbosity::kQuiet) return;
    std::lock_guard<std::mutex> lock(mutex_);
    clear_line_locked();
    std::fprintf(stderr, "kinegen: %s\n", message.c_str());
  }
  // Detail for --verbose only.
  void detail(const std::string& message) {
    if (verbosity_ != Verbosity::kVerbose) return;
    std::lock_guard<std::mutex> lock(mutex_);
    clear_line_locked();
    std::fprintf(stderr, "kinegen:   %s\n", message.c_str());
  }

  // The library's progress callbacks, printed as this log's stages.
  Progress progress_callbacks() {
    return {[this](const std::string& stage) { begin_stage(stage); },
            [this](const std::string& summary) { end_stage(summary); }};
  }

  // Starts a stage ("deriving Phi, Phi_q, nu, gamma"), ending the one before.
  void begin_stage(const std::string& name) {
    end_stage("");
    if (!progress()) return;
    std::unique_lock<std::mutex> lock(mutex_);
    stage_ = name;
    start_ = std::chrono::steady_clock::now();
    if (tty_) {
      std::fprintf(stderr, "kinegen: %s ...", stage_.c_str());
      std::fflush(stderr);
      line_open_ = true;
      stop_ = false;
      ticker_ = std::thread([this] { tick(); });
    }
  }
  // Ends the current stage; `summary` says what it produced ("Phi_q: 19 non-zeros").
  void end_stage(const std::string& summary) {
    if (stage_.empty()) return;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    if (ticker_.joinable()) ticker_.join();
    std::lock_guard<std::mutex> lock(mutex_);
    const double seconds = elapsed();
    if (verbosity_ == Verbosity::kVerbose) {
      clear_line_locked();
      std::fprintf(stderr, "kinegen: %s: %.3f s%s%s\n", stage_.c_str(), seconds,
                   summary.empty() ? "" : ", ", summary.c_str());
    } else {
      clear_line_locked();  // on a terminal: the progress line goes away when done
    }
    stage_.clear();
  }

 private:
  Log() : tty_(::isatty(STDERR_FILENO) == 1) {}

  double elapsed() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }
  void clear_line_locked() {
    if (!line_open_) return;
    std::fputs("\r\033[K", stderr);
    line_open_ = false;
  }
  // Rewrites the progress line with the elapsed time, twice a second, after the first second.
  void tick() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!wake_.wait_for(lock, std::chrono::milliseconds(500), [this] { return stop_; })) {
      const double seconds = elapsed();
      if (seconds < 1.0) continue;
      std::fprintf(stderr, "\r\033[Kkinegen: %s ... %.0f s", stage_.c_str(), seconds);
      std::fflush(stderr);
      line_open_ = true;
    }
  }

  Verbosity verbosity_ = Verbosity::kNormal;
  bool tty_;
  std::string stage_;
  std::chrono::steady_clock::time_point start_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::thread ticker_;
  bool stop_ = false;
  bool line_open_ = false;
};

// Ends a stage also when an exception leaves the scope (the error line then starts clean).
class StageScope {
 public:
  explicit StageScope(const std::string& name) { Log::global().begin_stage(name); }
  ~StageScope() {
    if (!done_) Log::global().end_stage("");
  }
  void done(const std::string& summary) {
    Log::global().end_stage(summary);
    done_ = true;
  }
  StageScope(const StageScope&) = delete;
  StageScope& operator=(const StageScope&) = delete;

 private:
  bool done_ = false;
};

}  // namespace kinegen::codegen
