#pragma once
// File output that is whole or absent: every output is written to a staging file beside its target, then renamed
// into place; several outputs of one run are staged together and published only once all are written; SIGINT and
// SIGTERM remove whatever is staged (docs/robustness.md).
#include <cstddef>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace topocal::util {

// Bad input or an output that cannot be written: the message is one line naming the file and the problem.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Bad input in a configuration-like file (JSON or YAML the user wrote): a kind of InputError, so that every
// reader's bad input is caught, and reported with exit 2, the same way.
class ConfigError : public InputError {
 public:
  using InputError::InputError;
};

// A measurement the data cannot support (too few spots identified, the pattern's centre not found, the sim-K zone
// not covered, the surface model failing the identified spots): refused with its reasons, never printed as if valid;
// exit code 4, distinct from a failed computation (1) and bad input (2).
class MeasurementRefused : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The outputs of one run, published all or nothing. What an output path is decides how it is written:
//  - a regular file or a new name: a staging file ".NAME.tmp-PID-TOKEN" (TOKEN unpredictable, the file created
//    exclusively) in the same directory, renamed over it at Commit (atomic; a failed or interrupted run leaves the
//    old file); a file this run read (NoteInput, with GuardInputs on) is refused;
//  - a symbolic link: written through — the file the link points to is replaced as above, the link stays;
//  - a FIFO, a character device (/dev/null, a terminal) or any path under /dev or /proc (/dev/stdout): written
//    directly at Commit (after every staged file is in place), never replaced by a regular file; a FIFO waits
//    for its reader at most 60 s without progress (TOPOCAL_STREAM_TIMEOUT_S), then the run fails naming it;
//  - "-", a directory, a block device or a socket: refused (InputError); "-" because every verb prints its summary
//    on standard output, which would mix with the file (/dev/stdout asks for exactly that).
// A file's directory must exist; a directory output is created with its parents (removed again if the run fails).
// Errors name the path and the cause
// (strerror; "disk full" for ENOSPC). Destroying an uncommitted set removes everything it staged.
class StagedOutputs {
 public:
  StagedOutputs();
  ~StagedOutputs();
  StagedOutputs(const StagedOutputs&) = delete;
  StagedOutputs& operator=(const StagedOutputs&) = delete;

  // Stages one file now (its bytes are on disk, or in memory for a stream, when this returns).
  void AddFile(const std::string& path, std::string_view content);
  // Stages a directory of outputs: returns a fresh staging directory to fill; at Commit its files are moved into
  // `path` (created if missing; other files already in `path` are left alone).
  std::string AddDirectory(const std::string& path);
  // Publishes everything. Throws InputError naming the path when a rename or a stream write fails.
  void Commit();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// One output, published at once (a StagedOutputs of one file).
void WriteFileAtomic(const std::string& path, std::string_view content);
// Reads a whole file; throws InputError naming the path if it cannot be read. The file is noted as an input.
std::string ReadFile(const std::string& path);
// From now on, every file read is an input of this run that no output may be written over (the command line calls
// it once in main(); a program linking the library decides for itself).
void GuardInputs();
// Notes `path` (an existing regular file) as an input of this run: with GuardInputs on, StagedOutputs refuses to
// write over it, whatever name the output gives it (compared by device and inode). ReadFile notes its files;
// readers that open files themselves (images, the fleet database) call this.
void NoteInput(const std::string& path);
// 64 random bits as 16 hex digits (the kernel's generator): a name nobody can predict.
std::string UnpredictableToken();

// SIGINT, SIGTERM and SIGHUP remove every path registered here (staging files and directories), then end the
// process with the same signal. Call InstallSignalCleanup() once at the start of main(), before any thread starts:
// it blocks these signals in the calling thread (so in every thread created later) and waits for them in a thread
// of its own. On a signal that thread parks every other thread first (so nothing re-creates a removed path and
// nothing runs the static destructors under it), then removes the paths with plain system calls.
void InstallSignalCleanup();
void RegisterCleanupPath(const std::string& path);
void UnregisterCleanupPath(const std::string& path);
// While one exists, the cleanup waits (a signal arriving meanwhile is acted on when it is destroyed): for renames
// that must not be cut in two, such as moving an old record aside and the new one into place.
class DeferSignalCleanup {
 public:
  DeferSignalCleanup();
  ~DeferSignalCleanup();
  DeferSignalCleanup(const DeferSignalCleanup&) = delete;
  DeferSignalCleanup& operator=(const DeferSignalCleanup&) = delete;
};

}  // namespace topocal::util
