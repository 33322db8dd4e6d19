// Progress of the library's long stages, reported to whoever runs them: library code does not
// print. The command line turns it into its progress lines (log.hpp); a test or an embedding
// program may leave it empty.
#pragma once

#include <functional>
#include <string>

namespace kinegen::codegen {

struct Progress {
  // A stage starts ("deriving Phi, Phi_q, nu and gamma (9 equations)").
  std::function<void(const std::string& stage)> begin;
  // The stage ends; `summary` says what it produced ("Phi_q: 19 structural non-zeros"), "" when
  // it has nothing to say or an exception ended it.
  std::function<void(const std::string& summary)> end;
};

// One stage, ended also when an exception leaves the scope.
class ProgressStage {
 public:
  ProgressStage(const Progress& progress, const std::string& name) : progress_(progress) {
    if (progress_.begin) progress_.begin(name);
  }
  ~ProgressStage() {
    if (!done_ && progress_.end) progress_.end("");
  }
  void done(const std::string& summary) {
    done_ = true;
    if (progress_.end) progress_.end(summary);
  }
  ProgressStage(const ProgressStage&) = delete;
  ProgressStage& operator=(const ProgressStage&) = delete;

 private:
  const Progress& progress_;
  bool done_ = false;
};

}  // namespace kinegen::codegen
