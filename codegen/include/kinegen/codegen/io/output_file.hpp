// Every file or stream the command line writes: generated headers, CSV, SVG, and standard output.
//
// A regular file (or a new name) is written to a temporary file created exclusively beside it
// (mkostemp: O_CREAT | O_EXCL, so a planted link is never followed) and renamed over the target
// on commit; until then the target is untouched, and an uncommitted, failed or interrupted
// run removes the temporary file (with install_signal_handlers, also one that SIGTERM,
// SIGHUP, SIGQUIT or a second SIGINT ends). A symbolic link at the
// target is replaced, not followed. Standard output ("-" or /dev/stdout), devices, pipes and
// anything under /dev or /proc are written in place, never replaced. Every write, fsync and
// close error is an OutputError (exit 1).
#pragma once

#include <memory>
#include <ostream>
#include <string>

namespace kinegen::codegen {

// The command line's signal handling, installed once at its start: the first SIGINT asks the
// run to stop at its next interruption point (base/interrupt.hpp: request_interrupt), so that
// analyze and simulate keep the rows written; a second SIGINT, SIGTERM, SIGHUP or SIGQUIT
// removes the pending temporary files and ends the process by that signal. Signals the process
// ignores (nohup) stay ignored. A program embedding the library (the Python module) does not
// call it and keeps its own handlers.
void install_signal_handlers();

class OutputFile {
 public:
  // "-" is standard output. Throws UsageError when the target cannot be opened or created.
  explicit OutputFile(const std::string& target);
  ~OutputFile();  // not committed: the temporary file is removed, the target left as it was
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  std::ostream& stream();
  // Throws OutputError if a write has failed so far (lets a long run stop early).
  void check();
  // Flushes, syncs and closes, then renames the temporary file into place. Throws OutputError.
  void commit();
  // Whether the target is replaced on commit (a regular file), not written in place (standard
  // output, a pipe, a device), where what was written is already out.
  bool replaces_target() const;
  // What messages call the target: its path, or "standard output".
  const std::string& name() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace kinegen::codegen
