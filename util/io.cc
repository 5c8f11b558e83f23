#include "util/io.h"

#include <dirent.h>
#include <fcntl.h>
#include <fmt/format.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <random>
#include <sstream>
#include <thread>

namespace topocal::util {
namespace {

namespace fs = std::filesystem;

// ---- paths removed when a signal ends the process -----------------------------------------------------------------

// Both are never destroyed: a signal may arrive while exit() runs the static destructors, and the cleanup thread
// must still find them whole.
std::recursive_mutex& CleanupMutex() {
  static auto* m = new std::recursive_mutex;
  return *m;
}
std::vector<std::string>& CleanupPaths() {
  static auto* paths = new std::vector<std::string>;
  return *paths;
}

// ---- writing --------------------------------------------------------------------------------------------------------

std::string ErrnoText(int e) {
  if (e == ENOSPC) return "disk full (No space left on device)";
  if (e == EDQUOT) return "disk quota exceeded";
  return std::strerror(e);
}

// Writes all of `content` to `fd`; false with errno set on failure.
bool WriteAll(int fd, std::string_view content) {
  const char* p = content.data();
  size_t left = content.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    p += n;
    left -= static_cast<size_t>(n);
  }
  return true;
}

// How long a stream output (a FIFO, /dev/stdout on a pipe) may make no progress: its open waits for a reader and its
// writes for the reader to read, and a reader that never comes must not hang a batch job for ever.
// TOPOCAL_STREAM_TIMEOUT_S overrides the 60 s.
int StreamTimeoutMs() {
  constexpr double kDefaultS = 60.0;
  const char* env = std::getenv("TOPOCAL_STREAM_TIMEOUT_S");
  if (env == nullptr || *env == '\0') return static_cast<int>(kDefaultS * 1000);
  char* end = nullptr;
  const double s = std::strtod(env, &end);
  if (*end != '\0' || !(s > 0 && s <= 86400)) {
    throw InputError(fmt::format("TOPOCAL_STREAM_TIMEOUT_S: '{}' is not a number of seconds in (0, 86400]", env));
  }
  return std::max(1, static_cast<int>(s * 1000));
}

// Opens a FIFO for writing without blocking: while no reader has it open (ENXIO) it is tried again until the
// timeout. The descriptor stays non-blocking; WriteStream waits for each write with poll().
int OpenFifoForWriting(const std::string& path, int timeout_ms) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  for (;;) {
    const int fd = ::open(path.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd >= 0 || errno != ENXIO) return fd;
    if (std::chrono::steady_clock::now() >= deadline) {
      throw InputError(fmt::format("{}: cannot be written: no reader opened the FIFO within {} s", path,
                                   timeout_ms / 1000.0));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

// Writes everything to a non-blocking descriptor, waiting at most `timeout_ms` for each step of progress.
void WriteStream(int fd, const std::string& path, std::string_view content, int timeout_ms) {
  const char* p = content.data();
  size_t left = content.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, p, left);
    if (n >= 0) {
      p += n;
      left -= static_cast<size_t>(n);
      continue;
    }
    if (errno == EINTR) continue;
    if (errno != EAGAIN) throw InputError(fmt::format("{}: cannot be written: {}", path, ErrnoText(errno)));
    pollfd pfd{fd, POLLOUT, 0};
    const int ready = ::poll(&pfd, 1, timeout_ms);
    if (ready == 0) {
      throw InputError(fmt::format("{}: cannot be written: the reader took nothing for {} s ({} of {} bytes written)",
                                   path, timeout_ms / 1000.0, content.size() - left, content.size()));
    }
    if (ready < 0 && errno != EINTR) throw InputError(fmt::format("{}: cannot be written: {}", path, ErrnoText(errno)));
  }
}

// The file a chain of symbolic links ends at (the path itself when it is no link; a dangling link's target).
fs::path ResolveLinks(const std::string& path) {
  fs::path p(path);
  constexpr int kMaxHops = 40;  // Linux's own limit (ELOOP)
  for (int hop = 0; hop < kMaxHops; ++hop) {
    struct stat st {};
    if (::lstat(p.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) return p;
    std::error_code ec;
    const fs::path target = fs::read_symlink(p, ec);
    if (ec) throw InputError(fmt::format("{}: cannot follow the link: {}", path, ec.message()));
    p = target.is_absolute() ? target : p.parent_path() / target;
  }
  throw InputError(fmt::format("{}: cannot be written: {}", path, std::strerror(ELOOP)));
}

// ".NAME.KIND-PID-TOKEN": the PID says which run it belongs to (a stale one is recognised by it), the token makes
// the name unpredictable, so nobody can plant a link where a staging directory will be.
std::string StagingName(const fs::path& final_path, const char* kind) {
  return fmt::format(".{}.{}-{}-{}", final_path.filename().string(), kind, ::getpid(), UnpredictableToken());
}

// (device, inode) of every file this run has read: an output that is one of them is refused. Off unless the
// program asks (GuardInputs): a library user may well rewrite a file it read.
std::atomic<bool> g_guard_inputs{false};
std::mutex& InputsMutex() {
  static auto* m = new std::mutex;
  return *m;
}
std::vector<std::pair<dev_t, ino_t>>& Inputs() {
  static auto* inputs = new std::vector<std::pair<dev_t, ino_t>>;
  return *inputs;
}

// Throws when `path` exists and is a file this run read.
void RefuseInputAsOutput(const std::string& path, const struct stat& st) {
  if (!g_guard_inputs.load()) return;
  std::lock_guard lock(InputsMutex());
  for (const auto& [dev, ino] : Inputs()) {
    if (dev == st.st_dev && ino == st.st_ino) {
      throw InputError(fmt::format("{}: is also an input of this run; refusing to overwrite it", path));
    }
  }
}

}  // namespace

// ---- StagedOutputs --------------------------------------------------------------------------------------------------

struct StagedOutputs::State {
  struct File {
    std::string path;     // as given, for messages
    fs::path final_path;  // where it is published (a link's target)
    fs::path staging;     // the staging file
  };
  struct Stream {
    std::string path;  // a FIFO, a character device, a path under /dev or /proc
    std::string content;
  };
  struct Directory {
    std::string path;
    fs::path staging;
  };
  std::vector<File> files;
  std::vector<Stream> streams;
  std::vector<Directory> directories;
  std::vector<fs::path> created;  // directories this set created (removed again if it is not committed)
  bool committed = false;

  void Track(const fs::path& p) { RegisterCleanupPath(p.string()); }
  // Creates `dir` and its missing parents, remembering the outermost one it created.
  void EnsureDirectory(const fs::path& dir, const std::string& for_path) {
    if (dir.empty()) return;
    fs::path outermost;
    for (fs::path p = dir; !p.empty(); p = p.parent_path()) {
      std::error_code ec;
      if (fs::exists(p, ec)) break;
      outermost = p;
      if (p == p.parent_path()) break;
    }
    if (outermost.empty()) {
      std::error_code ec;
      if (!fs::is_directory(dir, ec))
        throw InputError(fmt::format("{}: {} is not a directory", for_path, dir.string()));
      return;
    }
    Track(outermost);
    created.push_back(outermost);
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) throw InputError(fmt::format("{}: cannot create {}: {}", for_path, dir.string(), ec.message()));
  }
};

StagedOutputs::StagedOutputs() : state_(std::make_unique<State>()) {}

StagedOutputs::~StagedOutputs() {
  std::lock_guard lock(CleanupMutex());
  std::error_code ec;
  for (const auto& f : state_->files) {
    if (!state_->committed) fs::remove(f.staging, ec);
    UnregisterCleanupPath(f.staging.string());
  }
  for (const auto& d : state_->directories) {
    if (!state_->committed) fs::remove_all(d.staging, ec);
    UnregisterCleanupPath(d.staging.string());
  }
  for (auto it = state_->created.rbegin(); it != state_->created.rend(); ++it) {
    if (!state_->committed) fs::remove_all(*it, ec);
    UnregisterCleanupPath(it->string());
  }
}

void StagedOutputs::AddFile(const std::string& path, std::string_view content) {
  if (path.empty()) throw InputError("an output path is empty");
  // "-" is refused rather than guessed: every verb prints its summary on standard output, which would mix with the
  // file (/dev/stdout does that deliberately).
  if (path == "-")
    throw InputError("-: not an output path (topocal writes files; /dev/stdout writes to standard output)");
  // Paths under /dev and /proc (/dev/stdout, /dev/fd/N, /proc/self/fd/N) name an open stream or a device: written
  // directly, never renamed over.
  if (path.rfind("/dev/", 0) == 0 || path.rfind("/proc/", 0) == 0) {
    state_->streams.push_back({path, std::string(content)});
    return;
  }
  struct stat st {};
  mode_t mode = 0666;
  bool exists = false;
  if (::stat(path.c_str(), &st) == 0) {  // follows links: what would be written is the link's target
    if (S_ISDIR(st.st_mode)) throw InputError(fmt::format("{}: cannot be written: is a directory", path));
    if (S_ISFIFO(st.st_mode) || S_ISCHR(st.st_mode)) {
      state_->streams.push_back({path, std::string(content)});
      return;
    }
    if (!S_ISREG(st.st_mode)) {
      throw InputError(fmt::format("{}: cannot be written: not a regular file, FIFO or character device", path));
    }
    RefuseInputAsOutput(path, st);
    exists = true;
    mode = st.st_mode & 07777;
  } else if (errno != ENOENT) {
    throw InputError(fmt::format("{}: cannot be written: {}", path, ErrnoText(errno)));
  }
  State::File f;
  f.path = path;
  f.final_path = ResolveLinks(path);  // its directory must exist: a misspelt --out is an error, not a new tree
  f.staging = f.final_path.parent_path() / StagingName(f.final_path, "tmp");
  {
    std::lock_guard lock(CleanupMutex());
    state_->Track(f.staging);
    state_->files.push_back(f);
  }
  const int fd = ::open(f.staging.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, exists ? mode : 0666);
  if (fd < 0) throw InputError(fmt::format("{}: cannot be written: {}", path, ErrnoText(errno)));
  if (exists) (void)::fchmod(fd, mode);  // keep the permissions of the file it replaces
  const bool written = WriteAll(fd, content);
  const int write_errno = errno;
  if (::close(fd) != 0 && written) {
    throw InputError(fmt::format("{}: cannot be written: {}", path, ErrnoText(errno)));
  }
  if (!written) throw InputError(fmt::format("{}: cannot be written: {}", path, ErrnoText(write_errno)));
}

std::string StagedOutputs::AddDirectory(const std::string& path) {
  if (path.empty()) throw InputError("an output directory is empty");
  std::error_code ec;
  if (fs::exists(path, ec) && !fs::is_directory(path, ec)) {
    throw InputError(fmt::format("{}: exists and is not a directory", path));
  }
  fs::path target = fs::path(path).lexically_normal();
  if (target.filename().empty() && target.has_parent_path()) target = target.parent_path();  // "maps/"
  state_->EnsureDirectory(target.parent_path(), path);
  State::Directory d{path, target.parent_path() / StagingName(target, "staging")};
  {
    std::lock_guard lock(CleanupMutex());
    state_->Track(d.staging);
    state_->directories.push_back(d);
  }
  // Created exclusively: mkdir fails on anything already there, a planted link included (its name was
  // unpredictable, so this is a second line).
  if (::mkdir(d.staging.c_str(), 0777) != 0) {
    throw InputError(fmt::format("{}: cannot create {}: {}", path, d.staging.string(), ErrnoText(errno)));
  }
  return d.staging.string();
}

void StagedOutputs::Commit() {
  const int stream_timeout_ms = state_->streams.empty() ? 0 : StreamTimeoutMs();  // a bad setting before any output
  {
    // Held while publishing: a signal arriving now waits until every rename is done.
    std::lock_guard lock(CleanupMutex());
    for (const auto& f : state_->files) {
      std::error_code ec;
      fs::rename(f.staging, f.final_path, ec);
      if (ec) throw InputError(fmt::format("{}: cannot be written: {}", f.path, ec.message()));
    }
    for (const auto& d : state_->directories) {
      std::error_code ec;
      fs::path target = fs::path(d.path).lexically_normal();
      if (target.filename().empty() && target.has_parent_path()) target = target.parent_path();
      fs::create_directories(target, ec);
      if (ec) throw InputError(fmt::format("{}: cannot be created: {}", d.path, ec.message()));
      std::vector<fs::path> entries;
      for (const auto& e : fs::recursive_directory_iterator(d.staging, ec)) entries.push_back(e.path());
      if (ec) throw InputError(fmt::format("{}: cannot be listed: {}", d.staging.string(), ec.message()));
      for (const auto& e : entries) {
        const fs::path to = target / fs::relative(e, d.staging);
        if (fs::is_directory(e)) {
          fs::create_directories(to, ec);
        } else {
          fs::rename(e, to, ec);
        }
        if (ec) throw InputError(fmt::format("{}: cannot be written: {}", to.string(), ec.message()));
      }
      fs::remove_all(d.staging, ec);
    }
    state_->committed = true;  // what is published stays even if a stream below fails
  }
  for (const auto& s : state_->streams) {
    struct stat st {};
    const bool regular = ::stat(s.path.c_str(), &st) == 0 && S_ISREG(st.st_mode);  // /dev/stdout redirected to a file
    if (::stat(s.path.c_str(), &st) == 0 && S_ISFIFO(st.st_mode)) {
      const int timeout_ms = stream_timeout_ms;
      const int fd = OpenFifoForWriting(s.path, timeout_ms);
      if (fd < 0) throw InputError(fmt::format("{}: cannot be written: {}", s.path, ErrnoText(errno)));
      try {
        WriteStream(fd, s.path, s.content, timeout_ms);
      } catch (...) {
        ::close(fd);
        throw;
      }
      ::close(fd);
      continue;
    }
    const int fd = ::open(s.path.c_str(), O_WRONLY | O_CLOEXEC | (regular ? O_TRUNC : 0));
    if (fd < 0) throw InputError(fmt::format("{}: cannot be written: {}", s.path, ErrnoText(errno)));
    const bool ok = WriteAll(fd, s.content);
    const int e = errno;
    if (::close(fd) != 0 && ok) throw InputError(fmt::format("{}: cannot be written: {}", s.path, ErrnoText(errno)));
    if (!ok) throw InputError(fmt::format("{}: cannot be written: {}", s.path, ErrnoText(e)));
  }
}

void WriteFileAtomic(const std::string& path, std::string_view content) {
  StagedOutputs out;
  out.AddFile(path, content);
  out.Commit();
}

std::string UnpredictableToken() {
  std::random_device device;  // the kernel's getrandom
  return fmt::format("{:08x}{:08x}", device(), device());
}

void GuardInputs() { g_guard_inputs.store(true); }

void NoteInput(const std::string& path) {
  if (!g_guard_inputs.load()) return;
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return;
  std::lock_guard lock(InputsMutex());
  Inputs().emplace_back(st.st_dev, st.st_ino);
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot be opened for reading: {}", path, ErrnoText(errno)));
  NoteInput(path);
  // A regular file is read in one piece into a string of its size: streaming it through an ostringstream copied
  // every byte two to three times as the buffer grew (10 % of `unit calibrate`, which reads ~21 MB of
  // images to hash them). Anything whose size is unknown (a pipe) still streams.
  std::error_code ec;
  const auto size = std::filesystem::is_regular_file(path, ec) ? std::filesystem::file_size(path, ec) : 0;
  if (!ec && size > 0) {
    std::string bytes(static_cast<size_t>(size), '\0');
    in.read(bytes.data(), static_cast<std::streamsize>(size));
    if (in.bad() || in.gcount() != static_cast<std::streamsize>(size)) {
      throw InputError(fmt::format("{}: read error", path));
    }
    // A file that grew while being read: take the rest too, as the streaming read would.
    if (in.peek() == std::ifstream::traits_type::eof()) return bytes;
    std::ostringstream rest;
    rest << in.rdbuf();
    if (in.bad()) throw InputError(fmt::format("{}: read error", path));
    return bytes + rest.str();
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw InputError(fmt::format("{}: read error", path));
  return ss.str();
}

// ---- signals -------------------------------------------------------------------------------------------------------

void RegisterCleanupPath(const std::string& path) {
  std::lock_guard lock(CleanupMutex());
  CleanupPaths().push_back(path);
}

void UnregisterCleanupPath(const std::string& path) {
  std::lock_guard lock(CleanupMutex());
  auto& paths = CleanupPaths();
  const auto it = std::find(paths.rbegin(), paths.rend(), path);
  if (it != paths.rend()) paths.erase(std::next(it).base());
}

DeferSignalCleanup::DeferSignalCleanup() { CleanupMutex().lock(); }
DeferSignalCleanup::~DeferSignalCleanup() { CleanupMutex().unlock(); }

namespace {

// ---- stopping the world before the cleanup ------------------------------------------------------------------------
// While the cleanup removes staged paths, no other thread may run: one writing a map could re-create a staging
// directory after it was removed (1 kill in 150 left units/SN.tmp-PID/), and one leaving main() would run the static
// destructors under the cleanup (a kill during `unit calibrate` once ended in SIGSEGV instead of SIGTERM). So the
// cleanup thread first parks every other thread of the process in a signal handler that never returns, then removes
// the paths and ends the process. A parked thread may hold any lock, malloc's included, so from then on the cleanup
// calls only system calls: the tree removal below is written on openat/getdents64/unlinkat with buffers on the stack
// because std::filesystem allocates (no library offers an allocation-free removal).

std::atomic<int> g_parked{0};

extern "C" void ParkThisThread(int) {
  g_parked.fetch_add(1);
  for (;;) ::pause();
}

int ParkSignal() { return SIGRTMIN + 7; }  // glibc keeps SIGRTMIN-2 .. SIGRTMIN-1 for itself; nothing here uses +7

// Calls fn(name) for every entry of the open directory `fd` but "." and ".."; false if it cannot be read.
template <typename Fn>
bool ForEachEntry(int fd, Fn&& fn) {
  alignas(8) char buf[4096];
  for (;;) {
    const long n = ::syscall(SYS_getdents64, fd, buf, sizeof buf);
    if (n < 0) return false;
    if (n == 0) return true;
    for (long off = 0; off < n;) {
      // glibc's dirent64 has the kernel's linux_dirent64 layout
      const auto* d = reinterpret_cast<const struct dirent64*>(buf + off);
      off += d->d_reclen;
      if (std::strcmp(d->d_name, ".") != 0 && std::strcmp(d->d_name, "..") != 0) fn(d->d_name);
    }
  }
}

// Sends the park signal to every thread but this one, until a pass over /proc/self/task finds none it has not
// signalled (threads may be starting meanwhile), then waits up to 2 s for them to be parked. A thread that blocks
// the signal (none of ours does) is not waited for beyond that.
void ParkOtherThreads() {
  static pid_t signalled[4096];  // static storage: no allocation
  int count = 0;
  const pid_t self = static_cast<pid_t>(::syscall(SYS_gettid));
  const pid_t process = ::getpid();
  for (bool found_new = true; found_new && count < 4096;) {
    found_new = false;
    const int fd = ::open("/proc/self/task", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0) break;
    ForEachEntry(fd, [&](const char* name) {
      pid_t tid = 0;
      for (const char* c = name; *c >= '0' && *c <= '9'; ++c) tid = tid * 10 + (*c - '0');
      if (tid <= 0 || tid == self || count >= 4096) return;
      for (int i = 0; i < count; ++i)
        if (signalled[i] == tid) return;
      if (::syscall(SYS_tgkill, process, tid, ParkSignal()) == 0) signalled[count++] = tid;
      found_new = true;
    });
    ::close(fd);
  }
  const timespec ms{0, 1000000};
  for (int waited = 0; g_parked.load() < count && waited < 2000; ++waited) ::nanosleep(&ms, nullptr);
}

// Removes `name` (relative to `dirfd`) and, if it is a directory, everything under it; symbolic links are removed,
// not followed. Entries that appear meanwhile cannot (every other thread is parked), but the listing is repeated
// should the kernel's readdir miss entries removed under it.
void RemoveTree(int dirfd, const char* name, int depth) {
  if (::unlinkat(dirfd, name, 0) == 0 || errno == ENOENT) return;
  if (depth > 64) return;
  for (int attempt = 0; attempt < 8; ++attempt) {
    const int fd = ::openat(dirfd, name, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    if (fd < 0) return;
    ForEachEntry(fd, [&](const char* entry) { RemoveTree(fd, entry, depth + 1); });
    ::close(fd);
    if (::unlinkat(dirfd, name, AT_REMOVEDIR) == 0 || errno != ENOTEMPTY) return;
  }
}

}  // namespace

void InstallSignalCleanup() {
  static std::once_flag once;
  std::call_once(once, [] {
    struct sigaction park {};
    park.sa_handler = ParkThisThread;
    sigfillset(&park.sa_mask);  // nothing else runs in a parked thread
    ::sigaction(ParkSignal(), &park, nullptr);
    // A file-size limit (ulimit -f, as batch schedulers set): the write fails with EFBIG ("File too large") and the
    // run ends like any other failed write — one line, exit 2, nothing staged left — instead of the default
    // SIGXFSZ ending the process with its staging behind.
    ::signal(SIGXFSZ, SIG_IGN);
    sigset_t set;
    sigemptyset(&set);
    for (const int sig : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&set, sig);
    pthread_sigmask(SIG_BLOCK, &set, nullptr);
    std::thread([set] {
      int sig = 0;
      if (sigwait(&set, &sig) != 0) return;
      // Taken first, so that renames that must not be cut in two (DeferSignalCleanup) finish before the world stops;
      // never released: the process ends below.
      CleanupMutex().lock();
      ParkOtherThreads();
      for (auto it = CleanupPaths().rbegin(); it != CleanupPaths().rend(); ++it) RemoveTree(AT_FDCWD, it->c_str(), 0);
      // End with the signal itself, so the parent sees what happened (128 + signal in a shell). raise() reaches this
      // thread, where the signal is unblocked below.
      ::signal(sig, SIG_DFL);
      sigset_t one;
      sigemptyset(&one);
      sigaddset(&one, sig);
      pthread_sigmask(SIG_UNBLOCK, &one, nullptr);
      ::raise(sig);
      ::_exit(128 + sig);
    }).detach();
  });
}

}  // namespace topocal::util
